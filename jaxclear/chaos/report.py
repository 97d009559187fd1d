r"""One operating point characterised, as written by ``jaxclear chaos``: the Lyapunov spectrum
(:func:`~jaxclear.chaos.lyapunov`) and, on named channels of the same run, the stroboscopic
Poincare section with its period (:mod:`jaxclear.analysis.sections`), the 0-1 test and the
power spectral density (:mod:`.signals`); tables and figures in an output folder.

Files: ``exponents.csv`` (the spectrum, its standard error and spread, the e-folding time
:math:`1/\lambda`), ``running.csv`` (the running estimate after every counted interval),
``channels.csv`` (per channel: the period of its section, the 0-1 statistic, the PSD's peak),
``summary.json``, ``running.png``, ``spectrum.png``, ``poincare.png``: :class:`ChaosReport`, an
:class:`~jaxclear.AbstractResult` (``to_dict``, ``write``, ``summary``, ``plot``).
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass, field

import numpy as np

from .._errors import ParameterError, status_message
from .._results import AbstractResult, deprecated
from .._storage import atomic_write_json, atomic_write_text, jsonable
from ..analysis.sections import MAX_PERIOD, check_channels, detect_period, period_name, section_indices
from ..integrate import Settings
from ..model import Mechanism, crank_driver, crank_period
from . import figures
from .benettin import LyapunovResult
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
    Returns a :class:`ChaosReport` (unpacked as ``(LyapunovResult, [ChannelReport])``, the old
    return value, it warns: deprecated)."""
    channels = check_channels(mech, channels)
    found = crank_driver(mech)
    if found is None or float(found[1].speed) == 0.0:
        raise ParameterError(f"jaxclear chaos runs whole crank revolutions: mechanism {mech.name!r} has no turning "
                             "crank (AngleDriver with a non-zero speed)")
    period = float(crank_period(mech))
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
    return ChaosReport(mech.name, r, reports)


def _csv(rows, header) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue()


@dataclass
class ChaosReport(AbstractResult):
    """One operating point characterised (:func:`characterise`, ``jaxclear chaos``): the
    Lyapunov spectrum and what each channel shows; :meth:`to_dict` (``summary.json``),
    :meth:`write` (the files of the module docstring), :meth:`summary`, :meth:`plot` (the running
    estimate): :class:`~jaxclear.AbstractResult`.

    Attributes:
        mechanism: the mechanism's name.
        lyapunov: the :class:`~jaxclear.chaos.LyapunovResult` of the run (its ``status`` a
            :class:`~jaxclear.RESULTS` code).
        channels: a :class:`ChannelReport` per named channel.
    """

    mechanism: str
    lyapunov: LyapunovResult
    channels: list

    def __iter__(self):
        """Deprecated: ``result, reports = characterise(...)`` (the old return value)."""
        deprecated("unpacking characterise(...) as (result, reports)",
                   "the ChaosReport it returns (.lyapunov, .channels)")
        return iter((self.lyapunov, self.channels))

    def to_dict(self) -> dict:
        """The content of ``summary.json`` (JSON-ready: NaN and infinities as None)."""
        result = self.lyapunov
        ex = np.asarray(result.exponents)
        return jsonable({
            "mechanism": self.mechanism,
            "status": int(result.status), "status_message": status_message(int(result.status)),
            "exponents": [float(v) for v in ex], "stderr": [float(v) for v in np.asarray(result.stderr)],
            "spread": [float(v) for v in np.asarray(result.spread)],
            "largest": float(ex.max()), "sum": float(ex.sum()),
            "e_folding_time": float(1 / ex.max()) if ex.max() > 0 else None,
            "interval": float(result.interval), "intervals_counted": int(np.asarray(result.running).shape[0]),
            "renormalisations": int(np.sum(np.asarray(result.renormalisations))),
            "channels": {c.name: {"period": c.period, "longest_period_tested": c.longest, "zero_one_K": c.k,
                                  "zero_one_on": c.k_on,
                                  "psd_peak_Hz": c.peak_frequency} for c in self.channels},
        })

    def write(self, folder, *, plots: bool = True) -> list[str]:
        """``exponents.csv``, ``running.csv``, ``channels.csv``, ``summary.json`` and, with
        ``plots``, ``running.png``, ``spectrum.png``, ``poincare.png`` in ``folder``; returns
        their paths."""
        folder = os.fspath(folder)
        os.makedirs(folder, exist_ok=True)
        result = self.lyapunov
        ex = np.asarray(result.exponents)
        se, spread = np.asarray(result.stderr), np.asarray(result.spread)
        efold = [1 / v if v > 0 else float("inf") for v in ex]
        paths = [atomic_write_text(os.path.join(folder, "exponents.csv"), _csv(
            [[i + 1, f"{ex[i]:.10g}", f"{se[i]:.4g}", f"{spread[i]:.4g}", f"{efold[i]:.6g}"] for i in range(ex.size)],
            ["index", "exponent [1/s]", "stderr [1/s]", "spread [1/s]", "e-folding time [s]"]))]
        running = np.asarray(result.running)
        paths.append(atomic_write_text(os.path.join(folder, "running.csv"), _csv(
            [[f"{t:.10g}", *(f"{v:.10g}" for v in row)] for t, row in zip(np.asarray(result.times), running)],
            ["time [s]", *(f"exponent {i + 1} [1/s]" for i in range(ex.size))])))
        paths.append(atomic_write_text(os.path.join(folder, "channels.csv"), _csv(
            [[c.name, c.unit, period_name(c.period, c.longest), f"{c.k:.4g}", c.k_on, f"{c.peak_frequency:.6g}"]
             for c in self.channels],
            ["channel", "unit", "Poincare section", "0-1 test K", "0-1 test on", "PSD peak [Hz]"])))
        paths.append(atomic_write_json(os.path.join(folder, "summary.json"), self.to_dict(), indent=2))
        if plots:
            paths.append(self.plot(os.path.join(folder, "running.png")))
            figures.plot_spectra(self.channels, os.path.join(folder, "spectrum.png"))
            figures.plot_sections(self.channels, os.path.join(folder, "poincare.png"))
            paths += [os.path.join(folder, "spectrum.png"), os.path.join(folder, "poincare.png")]
        return paths

    def summary(self) -> str:
        """The spectrum (each exponent with its standard error, the sum, the e-folding time) and
        each channel's section, 0-1 test and spectral peak."""
        d = self.to_dict()
        lines = [f"{self.mechanism}: status {d['status']} ({d['status_message']}), {d['intervals_counted']} "
                 f"intervals of {d['interval']:.6g} s counted"]
        for i, (v, se) in enumerate(zip(d["exponents"], d["stderr"])):
            lines.append(f"  lambda_{i + 1:<2d} {_number(v, '1/s'):>16} +- {_number(se, '', '.2g')}")
        lines.append(f"  sum       {_number(d['sum'], '1/s'):>16} (phase-space contraction)")
        if d["e_folding_time"] is not None:
            lines.append(f"  e-folding time 1/lambda_1 = {_number(d['e_folding_time'], 's')}: a derivative through "
                         "the run loses its meaning after a few of these")
        for c in self.channels:
            lines.append(f"  {c.name}: Poincare section {c.period and f'period-{c.period}' or 'not periodic'}, "
                         + (f"0-1 test K = {c.k:.2f} (on {c.k_on})" if c.k == c.k else
                            f"0-1 test not run (fewer than {ZERO_ONE_MIN_SAMPLES} samples at "
                            f"{ZERO_ONE_PER_REVOLUTION} a revolution)")
                         + f", PSD peak {c.peak_frequency:.4g} Hz")
        return "\n".join(lines)

    def plot(self, path=None):
        """The running estimate of every exponent against time (:func:`.figures.plot_running`):
        the figure, or ``path`` once saved there."""
        fig = figures.plot_running(self.lyapunov, None if path is None else os.fspath(path))
        return fig if path is None else os.fspath(path)


def _number(value, unit: str, spec: str = ".4g") -> str:
    """``value`` with its unit for printing, ``n/a`` for None (a NaN or infinity in
    :meth:`ChaosReport.to_dict`)."""
    return "n/a" if value is None else f"{value:{spec}}{(' ' + unit) if unit else ''}"


def write_report(folder: str, mech: Mechanism, result, reports) -> dict:
    """Deprecated: :meth:`ChaosReport.write` (:func:`characterise` returns the report). Writes
    the files to ``folder``; returns the summary (:meth:`ChaosReport.to_dict`)."""
    deprecated("jaxclear.chaos.write_report(folder, mech, result, reports)",
               "characterise(...).write(folder) (a ChaosReport)")
    report = ChaosReport(mech.name, result, reports)
    report.write(folder)
    return report.to_dict()
