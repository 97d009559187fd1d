"""Records: synthetic ones made by jaxclear (tests, notebook, benchmark), writing them, and the
checks and cuts the fit applies to a measured one.

A record is a :class:`jaxclear.io.Measurements`: ``time_s`` ``(N,)`` [s], ``slider_acc_m_s2``
``(N,)`` [m/s^2] and optionally ``crank_angle_rad`` ``(N,)`` [rad], with ``# key: value``
metadata lines in its CSV form.
"""

from __future__ import annotations

import io as _stringio
import os

import numpy as np

from .. import io
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
                meta[f"true_{name}"] = current_value(mech, Accelerometer(), name)
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


def read_record(data) -> io.Measurements:
    """``data`` as a checked record: a Measurements or the path of a record CSV."""
    meas = io.read_measurements(data) if isinstance(data, (str, os.PathLike)) else data
    check_record(meas)
    return meas


def check_record(meas: io.Measurements):
    """Raise a ParameterError naming the sample and data row of the first bad value: columns of
    unequal length, a non-finite value, or times that do not strictly increase."""
    where = meas.path or "the record"
    t = np.asarray(meas.time_s, dtype=float)
    y = np.asarray(meas.slider_acc_m_s2, dtype=float)
    if t.ndim != 1 or y.shape != t.shape:
        raise ParameterError(f"{where}: time_s and slider_acc_m_s2 must be 1-D of equal length, got {t.shape}, {y.shape}")
    for name, arr in (("time_s", t), ("slider_acc_m_s2", y)):
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
