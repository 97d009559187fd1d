r"""One operating point characterised, as written by ``jaxclear chaos``: the Lyapunov spectrum
(:func:`~jaxclear.chaos.lyapunov`) and, on named channels of the same run, the stroboscopic
Poincare section with its period (:mod:`jaxclear.analysis.sections`), the 0-1 test and the
power spectral density (:mod:`.signals`); tables and figures in an output folder.

Files: ``exponents.csv`` (the spectrum, its standard error and spread, the e-folding time
:math:`1/\lambda`), ``running.csv`` (the running estimate after every counted interval),
``channels.csv`` (per channel: the period of its section, the 0-1 statistic, the PSD's peak),
``summary.json``, ``running.png``, ``spectrum.png``, ``poincare.png``.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field

import numpy as np

from .._errors import ParameterError, status_message
from .._storage import atomic_write_json, atomic_write_text
from ..analysis.sections import MAX_PERIOD, check_channels, detect_period, period_name, section_indices
from ..integrate import Settings
from ..model import Mechanism, crank_driver
from . import figures
from .lyapunov import lyapunov, trajectory
from .signals import ZERO_ONE_MIN_SAMPLES, channel_series, psd, zero_one_test

#: Samples a crank revolution that the 0-1 test runs on (the channel thinned; see :func:`characterise`).
ZERO_ONE_PER_REVOLUTION = 2


@dataclass
class ChannelReport:
    """What one channel of the run shows."""

    name: str
    unit: str
    section: np.ndarray  # (K,) the channel once per revolution
    period: int  # 0: not periodic within MAX_PERIOD
    k: float  # the 0-1 statistic
    k_on: str  # what the 0-1 test ran on
    longest: int  # the longest period the section can show (two repeats): min(16, (K - 1) // 2)
    frequency: np.ndarray = field(repr=False)
    density: np.ndarray = field(repr=False)

    @property
    def peak_frequency(self) -> float:
        return float(self.frequency[1:][np.argmax(self.density[1:])])


def characterise(mech: Mechanism, s: Settings, channels, *, per_revolution: int = 1, transient_revolutions: int = 0,
                 discard: int = 0, count: int | None = None, samples: int = 32, tol: float | None = None):
    """The spectrum and the channels' report of one run of ``s`` (whole crank revolutions,
    reported ``per_revolution`` times a revolution and renormalised at least as often,
    :mod:`.benettin`; the section is the last sample of every revolution after the transient).
    Returns ``(LyapunovResult, [ChannelReport])``."""
    channels = check_channels(mech, channels)
    found = crank_driver(mech)
    if found is None or float(found[1].speed) == 0.0:
        raise ParameterError(f"jaxclear chaos runs whole crank revolutions: mechanism {mech.name!r} has no turning "
                             "crank (AngleDriver with a non-zero speed)")
    period = 2 * math.pi / abs(float(found[1].speed))
    r = lyapunov(mech, s, interval=period / per_revolution, transient=transient_revolutions * period,
                 discard=discard, count=count, samples=samples, tol=tol)
    sol = trajectory(mech, s, r)
    stride = per_revolution * samples
    index = section_indices(int(sol.ts.shape[0]), stride, stride - 1)
    reports = []
    for name in channels:
        values, dt, unit = channel_series(mech, sol, name)
        sect = values[index]
        # the 0-1 test on the samples thinned to 2 a revolution: the forcing's harmonics then alias to
        # the frequencies 0 and pi of the sample index, outside the test's c range (pi/5, 4 pi/5);
        # at 4 a revolution the crank's harmonic sits at c = pi/2 and the resonance reads as K ~ 0 on a
        # chaotic run (measured); on the section itself a period-1 orbit is a constant plus the
        # integration's noise, whose random walk the test reads as chaos (K = 0.88, measured)
        series = values[::max(1, stride // ZERO_ONE_PER_REVOLUTION)]
        enough = series.size >= ZERO_ONE_MIN_SAMPLES
        k = zero_one_test(series)[0] if enough else float("nan")
        f, p = psd(values, dt)
        k_on = f"{ZERO_ONE_PER_REVOLUTION} samples a revolution" if enough else "too few samples"
        longest = max(0, min(MAX_PERIOD, (sect.size - 1) // 2))
        period = detect_period(sect, longest, rtol=1e-3, scale=np.max(np.abs(values)))
        reports.append(ChannelReport(name, unit, sect, period, k, k_on, longest, f, p))
    return r, reports


def _csv(rows, header) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


def write_report(folder: str, mech: Mechanism, result, reports) -> dict:
    """Write the tables and figures of :func:`characterise` to ``folder``; returns the summary."""
    import os

    os.makedirs(folder, exist_ok=True)
    ex = np.asarray(result.exponents)
    se, spread = np.asarray(result.stderr), np.asarray(result.spread)
    efold = [1 / v if v > 0 else float("inf") for v in ex]
    atomic_write_text(os.path.join(folder, "exponents.csv"), _csv(
        [[i + 1, f"{ex[i]:.10g}", f"{se[i]:.4g}", f"{spread[i]:.4g}", f"{efold[i]:.6g}"] for i in range(ex.size)],
        ["index", "exponent [1/s]", "stderr [1/s]", "spread [1/s]", "e-folding time [s]"]))
    running = np.asarray(result.running)
    atomic_write_text(os.path.join(folder, "running.csv"), _csv(
        [[f"{t:.10g}", *(f"{v:.10g}" for v in row)] for t, row in zip(np.asarray(result.times), running)],
        ["time [s]", *(f"exponent {i + 1} [1/s]" for i in range(ex.size))]))
    atomic_write_text(os.path.join(folder, "channels.csv"), _csv(
        [[c.name, c.unit, period_name(c.period, c.longest), f"{c.k:.4g}", c.k_on, f"{c.peak_frequency:.6g}"]
         for c in reports],
        ["channel", "unit", "Poincare section", "0-1 test K", "0-1 test on", "PSD peak [Hz]"]))
    summary = {
        "mechanism": mech.name,
        "status": int(result.status), "status_message": status_message(int(result.status)),
        "exponents": [float(v) for v in ex], "stderr": [float(v) for v in se], "spread": [float(v) for v in spread],
        "largest": float(ex.max()), "sum": float(ex.sum()),
        "e_folding_time": float(1 / ex.max()) if ex.max() > 0 else None,
        "interval": float(result.interval), "intervals_counted": int(running.shape[0]),
        "renormalisations": int(np.sum(np.asarray(result.renormalisations))),
        "channels": {c.name: {"period": c.period, "longest_period_tested": c.longest, "zero_one_K": c.k,
                              "zero_one_on": c.k_on,
                              "psd_peak_Hz": c.peak_frequency} for c in reports},
    }
    atomic_write_json(os.path.join(folder, "summary.json"), summary, indent=2)
    figures.plot_running(result, os.path.join(folder, "running.png"))
    figures.plot_spectra(reports, os.path.join(folder, "spectrum.png"))
    figures.plot_sections(reports, os.path.join(folder, "poincare.png"))
    return summary
