"""Records: synthetic ones made by jaxclear (tests, notebook, benchmark), writing them, and the
checks and cuts the fit applies to a measured one.

A record is a :class:`jaxclear.io.Measurements`: ``time_s`` ``(N,)`` [s], ``slider_acc_m_s2``
``(N,)`` [m/s^2] and optionally ``crank_angle_rad`` ``(N,)`` [rad], with ``# key: value``
metadata lines in its CSV form.
"""

from __future__ import annotations

import io as _stringio
import os
from dataclasses import dataclass, field

import numpy as np

from .. import io
from .._numbers import as_typed
from .._storage import atomic_write_text
from .._errors import ParameterError
from ..model import Mechanism
from ..analysis.sensor import Accelerometer
from ..integrate import settings as make_settings, simulate
from .parameters import current_value

#: Parameters whose true value a synthetic record names in its metadata.
TRUE_VALUES = ("stiffness", "restitution", "clearance", "friction")


def slider_role(mech: Mechanism) -> str:
    """The body whose acceleration is measured (role ``"slider"``)."""
    slider = mech.role("slider")
    if slider is None:
        raise ParameterError(
            f"mechanism {mech.name!r} has no 'slider' role: the measured signal (slider_acc_m_s2) has "
            "nothing to compare with"
        )
    return slider


def sensor_signal(mech: Mechanism, t_end: float, sample_rate_hz: float, sensor: Accelerometer | None = None,
                  rtol: float = 1e-10, atol: float = 1e-13, max_steps: int = 400_000):
    """Noise-free sensor output of the slider acceleration: ``(t, acc, crank_angle)``, each
    ``(n + 1,)`` with ``n = round(t_end * sample_rate_hz)`` ([s], [m/s^2], [rad] or None without a
    crank), simulated ``sensor.oversample`` times finer and filtered
    (:class:`jaxclear.analysis.sensor.Accelerometer`)."""
    sensor = Accelerometer() if sensor is None else sensor
    slider = slider_role(mech)
    n = int(round(t_end * sample_rate_hz))
    h = 1.0 / (sample_rate_hz * sensor.oversample)
    s = make_settings(n * sensor.oversample * h, n_out=n * sensor.oversample + 1, rtol=rtol, atol=atol,
                      max_steps=max_steps)
    sol = simulate(mech, s)
    acc = sensor(h, sol.coordinate(mech, slider, "x", derivative=2))
    crank = mech.role("crank")
    angle = sol.coordinate(mech, crank, "phi") if crank is not None else None
    k = slice(None, None, sensor.oversample)
    t = np.asarray(sol.ts)[k]
    return t, np.asarray(acc)[k], (None if angle is None else np.asarray(angle)[k])


def synthetic_record(mech: Mechanism, t_end: float, sample_rate_hz: float, sensor: Accelerometer | None = None,
                     snr_db: float | None = 20.0, seed: int = 0, path=None, rtol: float = 1e-10,
                     atol: float = 1e-13, metadata: dict | None = None) -> io.Measurements:
    """A record made by jaxclear: the sensor signal of :func:`sensor_signal` plus white Gaussian
    noise of standard deviation ``sigma = sqrt(mean(signal^2) / 10^(snr_db / 10))`` [m/s^2]
    (``snr_db=None``: none), with the true crank angle column. Written as a record CSV (with
    ``#`` metadata lines naming the true parameters) when ``path`` is given."""
    t, acc, angle = sensor_signal(mech, t_end, sample_rate_hz, sensor, rtol=rtol, atol=atol)
    sigma = 0.0
    if snr_db is not None:
        sigma = float(np.sqrt(np.mean(acc**2) / 10 ** (snr_db / 10)))
        acc = acc + np.random.default_rng(seed).normal(0.0, sigma, acc.shape)
    meta = {"source": f"jaxclear.fitting.synthetic_record, mechanism {mech.name}", "snr_db": snr_db,
            "noise_sigma_m_s2": sigma, "sensor": (sensor or Accelerometer()).describe(), "seed": seed}
    if mech.clearance_joints:
        for name in TRUE_VALUES:
            try:
                meta[f"true_{name}"] = as_typed(current_value(mech, Accelerometer(), name))  # R_B - R_J: no noise
            except (ParameterError, AttributeError):
                pass
    meta.update(metadata or {})
    meas = io.Measurements(time_s=t, slider_acc_m_s2=acc, crank_angle_rad=angle, metadata=meta,
                           path=os.fspath(path) if path is not None else "")
    if path is not None:
        write_measurements(path, meas)
    return meas


def write_measurements(path, meas: io.Measurements) -> str:
    """Write a record as CSV (``# key: value`` lines, header, rows; 12 significant digits),
    atomically. Returns the path."""
    cols = {name: getattr(meas, name) for name in meas.columns}
    buf = _stringio.StringIO()
    for key, value in meas.metadata.items():
        buf.write(f"# {key}: {value}\n")
    buf.write(",".join(cols) + "\n")
    np.savetxt(buf, np.column_stack(list(cols.values())), delimiter=",", fmt="%.12g")
    return atomic_write_text(path, buf.getvalue())


@dataclass
class FitRecord:
    """A record with any columns: ``time_s`` ``(N,)`` [s], ``columns`` name -> ``(N,)`` (the
    fitted ones), ``crank_angle_rad`` (for ``align="crank"``, or None), metadata and path."""

    time_s: np.ndarray
    columns: dict
    crank_angle_rad: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    path: str = ""


def _table(data) -> tuple[dict, dict, str]:
    """``(columns, metadata, path)`` of a Measurements, a mapping of columns, a pandas DataFrame
    (``time_s`` a column or the index) or the path of a record CSV (any columns)."""
    if isinstance(data, io.Measurements):
        return {n: getattr(data, n) for n in data.columns}, dict(data.metadata), data.path
    if hasattr(data, "columns") and hasattr(data, "index") and hasattr(data, "to_numpy"):  # a DataFrame
        cols = {str(c): data[c].to_numpy() for c in data.columns}
        if "time_s" not in cols and data.index.name == "time_s":
            cols["time_s"] = data.index.to_numpy()
        return cols, dict(getattr(data, "attrs", {}).get("metadata", {})), ""
    if isinstance(data, dict):
        return dict(data), {}, ""
    raise ParameterError(f"a record must be a jaxclear.io.Measurements, a DataFrame, a dict of columns or the path "
                         f"of a record CSV, got {type(data).__name__}")


def read_record(data, columns=("slider_acc_m_s2",)) -> FitRecord:
    """``data`` (a Measurements, a DataFrame, a dict of columns or the path of a record CSV) as a
    checked :class:`FitRecord` holding ``columns``. A CSV fitted on ``slider_acc_m_s2`` alone is
    read by :func:`jaxclear.io.read_measurements` (its checks and messages); any other by
    :func:`jaxclear.io.read_record_columns`."""
    columns = tuple(columns)
    if isinstance(data, (str, os.PathLike)):
        if columns == ("slider_acc_m_s2",):
            data = io.read_measurements(data)
        else:
            values, meta = io.read_record_columns(data, columns)
            data = io.Measurements(time_s=values["time_s"], slider_acc_m_s2=values.get("slider_acc_m_s2"),
                                   crank_angle_rad=values.get("crank_angle_rad"), metadata=meta, path=os.fspath(data))
            return _checked(FitRecord(values["time_s"], {c: values[c] for c in columns}, data.crank_angle_rad, meta,
                                      data.path))
    table, meta, path = _table(data)
    where = path or "the record"
    missing = [c for c in ("time_s", *columns) if c not in table or table[c] is None]
    if missing:
        raise ParameterError(f"{where}: missing column(s) {missing}; the record has {sorted(k for k, v in table.items() if v is not None)}")
    crank = table.get("crank_angle_rad")
    return _checked(FitRecord(np.asarray(table["time_s"], dtype=float),
                              {c: np.asarray(table[c], dtype=float) for c in columns},
                              None if crank is None else np.asarray(crank, dtype=float), meta, path))


def _checked(rec: FitRecord) -> FitRecord:
    check_record(rec)
    return rec


def check_record(meas):
    """Raise a ParameterError naming the sample and data row of the first bad value: columns of
    unequal length, a non-finite value, or times that do not strictly increase (``meas``: a
    :class:`FitRecord` or a Measurements)."""
    where = meas.path or "the record"
    t = np.asarray(meas.time_s, dtype=float)
    cols = meas.columns if isinstance(meas, FitRecord) else {"slider_acc_m_s2": meas.slider_acc_m_s2}
    cols = {n: np.asarray(v, dtype=float) for n, v in cols.items()}
    for name, y in cols.items():
        if t.ndim != 1 or y.shape != t.shape:
            raise ParameterError(f"{where}: time_s and {name} must be 1-D of equal length, got {t.shape}, {y.shape}")
    for name, arr in (("time_s", t), *cols.items()):
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise ParameterError(f"{where}: column {name!r} has a non-finite value at sample {int(bad[0])} "
                                 f"(data row {int(bad[0]) + 1})")
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        raise ParameterError(f"{where}: column 'time_s' is not strictly increasing at sample {int(bad[0]) + 1} "
                             f"(data row {int(bad[0]) + 2})")


def quiet_cut(t, y, t_cut: float, search: float) -> float:
    """Where to end a partial horizon [s]: the quietest sample of the record in ``[t_cut, t_cut +
    search]``, quiet meaning the smallest mean absolute sample-to-sample change over +-5 samples
    (an impact in progress has a large one). A horizon that ends inside an impact compares half
    an impulse, which can drive a parameter the rest of the data would fix (restitution) to the
    edge of its range; ending in free flight avoids that. ``t``, ``y``: ``(N,)``."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    inside = np.nonzero((t >= t_cut) & (t <= t_cut + search))[0]
    if inside.size < 3:
        return t_cut
    change = np.abs(np.diff(y, prepend=y[0]))
    m = 5
    activity = np.convolve(change, np.ones(2 * m + 1) / (2 * m + 1), mode="same")
    return float(t[inside[np.argmin(activity[inside])]])
