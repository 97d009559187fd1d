r"""What a fit compares: record columns mapped to named output channels.

A fit target is a mapping ``column -> channel spec``: the record's column ``column`` (same
samples as its ``time_s``) is compared with the simulated channel (a name of
:mod:`jaxclear.analysis.channels`, e.g. ``body:rocker:phi:acc``,
``point:slider:S:acc:x:frame=guide``, ``reaction:0:norm``, ``joint:0:ecc``) seen through its own
sensor model (:class:`~jaxclear.analysis.sensor.Accelerometer`: analogue 2nd-order Butterworth
low-pass, gain, bias; by default the fit's ``sensor``), with a weight ``w >= 0`` on its
normalised squared residual (:mod:`jaxclear.fitting.window`). A spec is

* a channel name (weight 1, the fit's sensor);
* a :class:`FitChannel`;
* a table (Python dict, TOML table) with ``channel`` and optionally ``weight``, ``cutoff_hz``,
  ``gain``, ``bias`` (a sensor of its own; the sampling ``oversample`` is the fit's).

Without a mapping the fit compares the column ``slider_acc_m_s2`` with
``body:SLIDER:x:acc`` (``SLIDER``: the mechanism's ``slider`` role) through the fit's sensor,
which is the historical behaviour of :func:`jaxclear.fit`. In TOML (``jaxclear fit --channels
FILE.toml``)::

    [channels.rocker_acc_rad_s2]
    channel = "body:rocker:phi:acc"
    weight = 1.0
    cutoff_hz = 2000.0

    [channels]
    slider_acc_m_s2 = "point:slider:S:acc:x"   # a bare name is a spec too
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass
from typing import Mapping

from .._errors import ParameterError, check_range
from .._storage import read_text
from ..analysis import channels as named
from ..analysis.sensor import Accelerometer
from ..model import Mechanism
from .records import slider_role

#: The record column of the default target (the slider acceleration).
DEFAULT_COLUMN = "slider_acc_m_s2"
#: Keys of a spec table.
SPEC_KEYS = ("channel", "weight", "cutoff_hz", "gain", "bias")


@dataclass(frozen=True)
class FitChannel:
    """One fitted channel: ``channel`` (a :mod:`jaxclear.analysis.channels` name), ``weight``
    (>= 0, on the normalised squared residual) and ``sensor`` (None: the fit's sensor)."""

    channel: str
    weight: float = 1.0
    sensor: Accelerometer | None = None

    def describe(self) -> dict:
        return {"channel": self.channel, "weight": self.weight,
                "sensor": None if self.sensor is None else self.sensor.describe()}


def _spec(column: str, spec, oversample: int) -> FitChannel:
    """A :class:`FitChannel` from a name, a FitChannel or a table (module docstring)."""
    if isinstance(spec, FitChannel):
        return spec
    if isinstance(spec, str):
        return FitChannel(spec)
    if isinstance(spec, Mapping):
        bad = sorted(set(spec) - set(SPEC_KEYS))
        if bad or "channel" not in spec:
            raise ParameterError(f"channel spec of column {column!r}: needs 'channel'; unknown key(s) {bad}; "
                                 f"allowed: {list(SPEC_KEYS)}")
        sensor = None
        if any(k in spec for k in ("cutoff_hz", "gain", "bias")):
            sensor = Accelerometer(spec.get("cutoff_hz"), gain=spec.get("gain", 1.0), bias=spec.get("bias", 0.0),
                                   oversample=oversample)
        return FitChannel(str(spec["channel"]), float(spec.get("weight", 1.0)), sensor)
    raise ParameterError(f"channel spec of column {column!r} must be a channel name, a FitChannel or a table with "
                         f"'channel', got {type(spec).__name__}")


def resolve_targets(mech: Mechanism, channels, sensor: Accelerometer) -> tuple[tuple[str, FitChannel], ...]:
    """``((column, FitChannel with its sensor), ...)`` in the mapping's order, checked against
    ``mech`` (channel names, weights, one oversampling for all sensors). ``channels`` None: the
    slider-acceleration default (module docstring)."""
    if channels is None:
        return ((DEFAULT_COLUMN, FitChannel(f"body:{slider_role(mech)}:x:acc", 1.0, sensor)),)
    if not isinstance(channels, Mapping) or not channels:
        raise ParameterError("channels must be a non-empty mapping: record column -> channel spec")
    out = []
    for column, spec in channels.items():
        if column == "time_s":
            raise ParameterError("channels: 'time_s' is the record's time, not a fitted column")
        fc = _spec(str(column), spec, sensor.oversample)
        named.unit(mech, fc.channel)  # ParameterError naming a bad channel
        check_range(f"weight of column {column!r}", fc.weight, low=0.0)
        if not math.isfinite(fc.weight):
            raise ParameterError(f"weight of column {column!r} must be finite, got {fc.weight!r}")
        s = sensor if fc.sensor is None else fc.sensor
        if s.oversample != sensor.oversample:
            raise ParameterError(f"the sensor of column {column!r} has oversample {s.oversample}, the fit's "
                                 f"{sensor.oversample}: all channels share the simulation grid")
        out.append((str(column), FitChannel(fc.channel, fc.weight, s)))
    if not any(fc.weight > 0 for _, fc in out):
        raise ParameterError("channels: every weight is 0; nothing would be fitted")
    return tuple(out)


def read_channels_toml(path) -> dict:
    """The ``[channels]`` table of a TOML file (module docstring): column -> spec."""
    path = os.fspath(path)
    text = read_text(path, "channels file")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ParameterError(f"{path}: not valid TOML ({err})") from None
    table = data.get("channels")
    if not isinstance(table, dict) or not table:
        raise ParameterError(f"{path}: expected a [channels] table mapping record columns to channel specs")
    return table
