"""Mechanisms as files: :mod:`jaxclear.mechanisms.files` (mechanism files, TOML, read with
validation and written: ``load_mechanism``, ``save_mechanism``, ``loads_mechanism``,
``dumps_mechanism``), :mod:`jaxclear.mechanisms.tables` (the ``profile`` tables of drivers and
loads and a spring's curve tables in those files, CSV tables) and :mod:`jaxclear.mechanisms.presets`
(the reference mechanisms with their sources; each ships as a file in this folder,
``flores-slider-crank.toml``, ...). ``jaxclear.presets`` and ``jaxclear.mechanism_files`` are the
modules ``presets`` and ``files`` of this package."""

from .files import dumps_mechanism, is_mechanism_file, load_mechanism, loads_mechanism, save_mechanism
from .presets import PRESETS, preset, preset_file, preset_names

__all__ = ["dumps_mechanism", "is_mechanism_file", "load_mechanism", "loads_mechanism", "save_mechanism", "PRESETS",
           "preset", "preset_file", "preset_names"]
