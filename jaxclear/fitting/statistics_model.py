r"""The model's sensor signal at every grid point of a statistics fit, revolution by revolution
(:func:`~jaxclear.fitting.statistics_fit.fit_statistics`).

One run: the mechanism with the row's parameter values, started up from its own initial state
(the preset's: crank angle ``angle0``, journal where the mechanism puts it, plus a replicate's
offset), integrated by :func:`jaxclear.simulate` on a grid ``oversample`` times finer than the
record's sample spacing :math:`\Delta t` [s]; its slider acceleration [m/s^2] goes through the
accelerometer's low-pass (:meth:`jaxclear.analysis.sensor.Accelerometer.filter`, continuous in
time, exact for piecewise-linear input; gain, bias and noise are applied later, in NumPy) and is
sampled every :math:`\Delta t` from :math:`t_0 = N_\text{tr} T + \varphi/|\omega|` on, where
:math:`N_\text{tr}` is the number of start-up revolutions left out (``transient_revolutions``),
:math:`T` the crank period and :math:`\varphi` the record's crank angle at its first sample
relative to ``angle0`` (so that the model's revolution blocks begin at the record's crank angle).
Returned: ``(runs, blocks, n_b)`` samples [m/s^2] and each run's status.

Several runs per grid point (``replicates``) start from journal offsets ``offset_x`` that differ
by :data:`REPLICATE_OFFSET` of the clearance (a few tens of nanometres): the start-up is
chaotic (largest Lyapunov exponent 444 1/s on the Flores benchmark at 5000 rpm), so after
the transient revolutions they are independent draws of the same motion; shorter runs keep one
run's output (about 1 kB per sample) small.

The runs of a chunk of rows are one compiled program: side by side (``jax.vmap``) on
accelerators, one after another (``jax.lax.map``) on CPU devices with single-kernel loops
(:func:`jaxclear.sweep.lanes.lanes_one_by_one`, the sweep's and the sampler's rule). A failed run
(``Solution.status`` not 0, e.g. the step limit; ``throw=False``) or one whose signal is not
finite is reported as failed, never as NaN statistics.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .. import params
from ..analysis.sensor import Accelerometer
from ..integrate import Settings, default_settings, settings_or_default, simulate
from ..model import Mechanism
from ..sweep.lanes import lanes_one_by_one, over_lanes
from .records import slider_role
from .statistics import block_starts

#: Spacing of the replicates' start offsets ``offset_x``, as a fraction of the clearance [-].
REPLICATE_OFFSET = 1e-4
#: Status of a run whose status was 0 but whose signal is not finite.
NOT_FINITE = -1


@dataclass(frozen=True)
class SignalPlan:
    """The static layout of a run (hashable: it is part of the compiled program).

    Attributes:
        names: mechanism parameters set from a row, in row order (the row's last entry is the
            replicate's ``offset_x`` shift [m]).
        dt: record sample spacing [s]; oversample: simulation samples per record sample.
        samples_per_revolution: ``T / dt``; blocks: revolution blocks per run; nb: samples per block.
        first: index (simulation grid) of the first block's first sample.

    How each run is integrated is the :class:`~jaxclear.Settings` given beside the plan
    (:func:`run_settings`).
    """

    names: tuple
    dt: float
    oversample: int
    samples_per_revolution: float
    blocks: int
    nb: int
    first: int

    @property
    def n_out(self) -> int:
        """Simulation output samples: up to the last block's last sample."""
        last = block_starts(self.blocks, self.samples_per_revolution)[-1] + self.nb - 1
        return int(self.first + self.oversample * last + 1)

    def index(self) -> np.ndarray:
        """Simulation-grid indices of the block samples ``(blocks, nb)``."""
        starts = block_starts(self.blocks, self.samples_per_revolution)
        return self.first + self.oversample * (starts[:, None] + np.arange(self.nb)[None, :])


def make_plan(mech: Mechanism, names, dt: float, oversample: int, period: float, nb: int, blocks: int,
              transient_revolutions: int, phase: float) -> SignalPlan:
    """The :class:`SignalPlan` of a record sampled every ``dt`` [s]: crank ``period`` [s],
    ``phase`` [rad] the record's crank angle at its first sample minus the mechanism's ``angle0``
    (taken modulo 2 pi in the crank's direction of rotation)."""
    h = dt / oversample
    speed = float(params.get(mech, "speed"))
    lag = (math.copysign(1.0, speed) * phase) % (2.0 * math.pi) * period / (2.0 * math.pi)  # [s]
    first = int(round((transient_revolutions * period + lag) / h))
    return SignalPlan(tuple(names), float(dt), int(oversample), float(period / dt), int(blocks), int(nb), first)


def given_settings(settings: Settings | None, stacklevel: int = 4, **old) -> Settings:
    """The settings of a statistics fit's runs before it replaces what it owns
    (:func:`run_settings`): ``settings``, else ``Settings``' defaults with the deprecated
    ``rtol=``, ``atol=``, ``max_steps=`` keywords ``old`` (a ``DeprecationWarning``; with
    ``settings`` too, a :class:`~jaxclear.ParameterError`; ``stacklevel`` as
    :func:`~jaxclear.integrate.deprecated_keywords`'). Given none, the runs are those of before
    (rtol 1e-6, atol 1e-9, 400,000 steps: ``Settings``' defaults)."""
    return settings_or_default("fit_statistics", settings, default_settings(), stacklevel, **old)


def run_settings(plan: SignalPlan, settings: Settings) -> Settings:
    """The settings of every run of ``plan``: ``settings`` whole, with what the statistics fit
    owns replaced: ``t_start`` 0 and ``t_end`` (each run from start-up to the last block's last
    sample), ``n_out`` (the plan's simulation grid, ``oversample`` samples per record sample),
    ``throw`` False (a failed run is a status: its grid point is reported and left out) and
    ``progress`` False (the fit's bar counts the runs)."""
    h = plan.dt / plan.oversample
    return dataclasses.replace(settings, t_start=0.0, t_end=jnp.asarray((plan.n_out - 1) * h, dtype=float),
                               n_out=plan.n_out, throw=False, progress=False)


def _run(mech: Mechanism, sensor: Accelerometer, plan: SignalPlan, settings: Settings, row):
    """One run (module docstring): ``((blocks, nb) filtered slider acceleration [m/s^2], status)``."""
    m = params.replace_many(mech, {n: row[i] for i, n in enumerate(plan.names)})
    m = params.replace(m, "offset_x", params.get(m, "offset_x") + row[-1])
    h = plan.dt / plan.oversample
    sol = simulate(m, run_settings(plan, settings))
    acc = sol.coordinate(m, slider_role(m), "x", derivative=2)
    y = sensor.filter(h, acc)[jnp.asarray(plan.index())]
    status = jnp.where((sol.status == 0) & ~jnp.all(jnp.isfinite(y)), NOT_FINITE, sol.status)
    return y, status.astype(jnp.int32)


@eqx.filter_jit
def _chunk(mech: Mechanism, sensor: Accelerometer, plan: SignalPlan, settings: Settings, rows):
    """The runs of ``rows`` ``(B, P + 1)``: ``((B, blocks, nb), (B,))``."""
    one = lambda r: _run(mech, sensor, plan, settings, r)  # noqa: E731
    return over_lanes(one, rows)


def default_chunk() -> int:
    """Rows per compiled chunk: 4 where runs go one after another (the chunk only sets how often
    the progress bar moves), 32 side by side (what fills an accelerator)."""
    return 4 if lanes_one_by_one() else 32


def run_rows(mech: Mechanism, sensor: Accelerometer, plan: SignalPlan, rows, chunk: int | None = None,
             bar=None, settings: Settings | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Every row's run, ``chunk`` rows per call of one compiled program (the last chunk padded
    with copies of its last row). ``rows`` ``(R, P + 1)``; returns ``(R, blocks, nb)`` [m/s^2]
    and ``(R,)`` statuses. ``bar``: a tqdm bar advanced by the rows done; ``settings``: how the
    runs are integrated (:func:`run_settings`; default ``Settings``' defaults)."""
    settings = default_settings() if settings is None else settings
    rows = np.asarray(rows, dtype=float)
    chunk = default_chunk() if chunk is None else int(chunk)
    out, status = [], []
    for i in range(0, len(rows), chunk):
        part = rows[i:i + chunk]
        pad = np.concatenate([part, np.repeat(part[-1:], chunk - len(part), axis=0)])
        y, st = _chunk(mech, sensor, plan, settings, jnp.asarray(pad))
        out.append(np.asarray(y)[: len(part)])
        status.append(np.asarray(st)[: len(part)])
        if bar is not None:
            bar.update(len(part))
    return np.concatenate(out), np.concatenate(status)


def replicate_offsets(mech: Mechanism, replicates: int) -> np.ndarray:
    """The replicates' ``offset_x`` shifts [m]: ``k * REPLICATE_OFFSET * clearance``, ``(replicates,)``."""
    return np.arange(replicates) * REPLICATE_OFFSET * float(params.get(mech, "clearance"))
