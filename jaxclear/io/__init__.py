"""Files in and out: :mod:`jaxclear.io.timeseries` (a run's time series as CSV, NetCDF and a
pandas DataFrame; JSON) and :mod:`jaxclear.io.records` (measured data: ``read_measurements``,
``Measurements``, the columns of a record file). ``jaxclear.io`` exports both modules' names
(``jc.io.write_json(...)``, as before the package)."""

from .timeseries import (COLUMN_UNITS, CONTACT_COLUMNS, SLIDER_COLUMNS, UNIT_SUFFIXES, column_unit, output_column,
                         timeseries_columns, timeseries_dataset, timeseries_frame, timeseries_table, write_json,
                         write_table_csv, write_timeseries_csv, write_timeseries_netcdf)
from .records import (OPTIONAL_MEASUREMENT_COLUMNS, REQUIRED_MEASUREMENT_COLUMNS, Measurements, read_measurements,
                      read_record_columns)

__all__ = ["COLUMN_UNITS", "CONTACT_COLUMNS", "SLIDER_COLUMNS", "UNIT_SUFFIXES", "column_unit", "output_column",
           "timeseries_columns", "timeseries_dataset", "timeseries_frame", "timeseries_table", "write_json",
           "write_table_csv", "write_timeseries_csv", "write_timeseries_netcdf", "OPTIONAL_MEASUREMENT_COLUMNS",
           "REQUIRED_MEASUREMENT_COLUMNS", "Measurements", "read_measurements", "read_record_columns"]
