"""How to integrate: the solver choice, tolerances, output grid and adjoint (:class:`Settings`)."""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax.numpy as jnp

from .._errors import ParameterError, is_concrete
from .._types import Array, Float
from .dynamics import Baumgarte

SOLVERS = {
    "tsit5": diffrax.Tsit5,
    "dopri5": diffrax.Dopri5,
    "dopri8": diffrax.Dopri8,
    "bosh3": diffrax.Bosh3,
    "kvaerno5": diffrax.Kvaerno5,
}
"""Solver name (``Settings.solver``) -> diffrax solver class."""


#: Values of ``Settings.adjoint``: the error-controlled sensitivities, then diffrax's adjoints
#: through its loop.
ADJOINTS = ("sensitivity", "recursive", "forward", "direct")


#: Largest number of output samples of one run (``n_out``): ~1 kB per sample of a small
#: mechanism (states, accelerations, reactions, contact outputs) makes this ~2 GB.
MAX_OUT_SAMPLES = 2_000_000


class Settings(eqx.Module):
    """How to integrate.

    Attributes:
        t_end: end time [s] (array leaf: may be swept).
        t_start: start time [s].
        n_out: number of output samples on the uniform grid ``[t_start, t_end]``.
        solver: one of :data:`SOLVERS` (default ``"tsit5"``).
        rtol, atol: tolerances of the adaptive PID step controller (relative, absolute [SI]).
        dt0: first step [s]; ``None`` lets diffrax choose.
        dtmax: largest step [s] or ``None``.
        max_steps: step limit; reaching it is an error (or status 1 with ``throw=False``).
        baumgarte: stabilization gains (alpha, beta) [1/s].
        adjoint: how derivatives of the run are computed. ``"sensitivity"`` (default): every
            derivative (``jax.jvp``, ``jax.jacfwd``, ``jax.grad``, ``jax.vjp``) is the
            error-controlled forward sensitivity of :mod:`jaxclear.integrate.sensitivity`: the
            tangents of the perturbed inputs are integrated with the state, take part in the
            step-size control and carry the memory rules' derivatives; reverse mode costs one
            tangent per perturbed scalar input. Differentiating through diffrax's loop instead
            (the derivative of the discretization whose steps were sized for the values only;
            after a contact ends it is off by 0.1 % to several times the derivative at the
            default tolerances and does not converge with them over several impacts, see the
            sensitivities theory page and ``benchmarks/bench_gradients.py``): ``"recursive"`` (reverse mode with checkpoints),
            ``"forward"`` (forward mode), ``"direct"``.
        derivative_tolerance: the sensitivity solve's ``rtol`` and ``atol`` are the values'
            times this (default 0.1; in (0, 1]): a derivative needs a tighter tolerance than a
            value to be smooth in the parameters, since the step sequence changes with them
            and a misfit's derivative is a sum whose terms cancel (measured on
            ``benchmarks/bench_gradients.py``'s worst misfit, slider-crank friction 0.1,
            n = 1: the derivatives at parameter values 1e-7 apart departed from a straight
            line by 1.7e-3 at rtol 1e-6, by 2.4e-5 at 1e-7, for 1.07-1.24x the Jacobian's
            time where contacts dominate (its steps are spent at the onsets), up to 2-3.5x
            on the lubricated joint, whose smooth film's steps the tolerance sets). The values of a plain
            run keep ``rtol``; those returned with derivatives come from the sensitivity
            solve. Only with ``adjoint="sensitivity"``.
        checkpoints: number of checkpoints of reverse mode (``None``: diffrax's default,
            logarithmic in ``max_steps``); fewer checkpoints = less memory, more recomputation.
        throw: raise errors (True) or report them in ``Solution.status`` (False; sweeps).
        progress: show a progress bar while integrating.
        continuous_contact_after: a contact lasting longer than this [s] is classed as
            continuous contact (mode 2) instead of impact (mode 1).
        allow_free_dof: a driven mechanism normally has all its motion determined by the
            drivers (plus the journal's freedom); set True to allow additional free motion.
        stages: how an explicit Runge-Kutta solver evaluates its stages: ``"loop"``
            (default; diffrax's own ``while_loop`` over the stages, one copy of the vector field
            for every stage) or ``"unrolled"`` (:class:`UnrolledExplicitRK`, straight-line
            stages). The two compute the same step. Measured 2026-11-25 on the benchmark
            slider-crank (one run, 2 cores): the loop compiles in about half the time (2.7-3.2 s
            against 4.7-6.1 s of XLA compilation) and ran 17-30 % faster per step (28.7 against
            37-42 us); on the four-bar the unrolled form was 10 % faster per step. Under
            ``jax.vmap`` the loop is faster still (1.7x per member at a batch of 32).
        exact_onsets: end the step that crosses into contact just past the onset (a rejected
            step per onset, :class:`~jaxclear.integrate.solvers.OnsetController`), so the
            dissipative laws use the approach speed at the onset throughout the contact
            (default True; False: the onset is found only after the step, whose force used the
            approach speed of its start).
        sampling: how the output samples are written: ``"loop"`` (default; diffrax's saving,
            one sample per iteration of a loop inside each step) or ``"block"``
            (:class:`~jaxclear.integrate.sampling.SampleWriter`: all of a step's samples at
            once, a step ending by its 64th sample). Measured 2026-11-25 on the benchmark (1
            revolution, about 1200 steps, Intel Xeon): with XLA's single-kernel loops
            (jaxclear's default, ``jaxclear/_xla_flags.py``) "loop" is faster on every grid
            (241 samples 7.6 ms against 12.0 ms, 24,001 samples 20.0 ms against 23.0 ms);
            without them (``JAXCLEAR_SMALL_LOOP_BYTES=0``) "block" pays from about 10 samples
            per step (24,001 samples 52.5 ms against 63 ms, 241 samples 45 ms against 31 ms).
            The fits use "block" (their wall time is the same either way with single-kernel
            loops: the rig record's fit 54 s against 55 s).
    """

    t_end: Float[Array, ""]
    t_start: float = eqx.field(static=True, default=0.0)
    n_out: int = eqx.field(static=True, default=1001)
    solver: str = eqx.field(static=True, default="tsit5")
    rtol: float = eqx.field(static=True, default=1e-6)
    atol: float = eqx.field(static=True, default=1e-9)
    dt0: float | None = eqx.field(static=True, default=None)
    dtmax: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=400_000)
    baumgarte: Baumgarte = eqx.field(default_factory=lambda: Baumgarte(jnp.asarray(5.0), jnp.asarray(5.0)))
    adjoint: str = eqx.field(static=True, default="sensitivity")
    derivative_tolerance: float = eqx.field(static=True, default=0.1)
    checkpoints: int | None = eqx.field(static=True, default=None)
    throw: bool = eqx.field(static=True, default=True)
    progress: bool = eqx.field(static=True, default=False)
    continuous_contact_after: float = eqx.field(static=True, default=2e-4)
    allow_free_dof: bool = eqx.field(static=True, default=False)
    stages: str = eqx.field(static=True, default="loop")
    exact_onsets: bool = eqx.field(static=True, default=True)
    sampling: str = eqx.field(static=True, default="loop")

    def __check_init__(self):
        if self.solver not in SOLVERS:
            raise ParameterError(f"unknown solver {self.solver!r}; valid: {sorted(SOLVERS)}")
        if self.stages not in ("unrolled", "loop"):
            raise ParameterError(f"stages must be 'unrolled' or 'loop', got {self.stages!r}")
        if self.sampling not in ("loop", "block"):
            raise ParameterError(f"sampling must be 'loop' or 'block', got {self.sampling!r}")
        if self.adjoint not in ADJOINTS:
            raise ParameterError(f"adjoint must be one of {list(ADJOINTS)}, got {self.adjoint!r}")
        if not (0 < self.rtol < 1):
            raise ParameterError(f"rtol = {self.rtol:g} outside the allowed range (0, 1)")
        if not (self.atol > 0):
            raise ParameterError(f"atol = {self.atol:g} outside the allowed range (0, inf)")
        if not (0 < self.derivative_tolerance <= 1):
            raise ParameterError(
                f"derivative_tolerance = {self.derivative_tolerance:g} outside the allowed range (0, 1]")
        if not 2 <= self.n_out <= MAX_OUT_SAMPLES:
            raise ParameterError(
                f"n_out = {self.n_out} output samples outside the allowed range [2, {MAX_OUT_SAMPLES}] "
                "(CLI: --n-out, or fewer --revolutions, whose default n_out grows with them); the outputs "
                f"take about 1 kB per sample, and this bound is checked before anything is compiled"
            )
        if self.dt0 is not None and not self.dt0 > 0:
            raise ParameterError(f"dt0 = {self.dt0:g} s outside the allowed range (0, inf)")
        if self.dtmax is not None and not self.dtmax > 0:
            raise ParameterError(f"dtmax = {self.dtmax:g} s outside the allowed range (0, inf)")
        if self.max_steps < 1:
            raise ParameterError(f"max_steps = {self.max_steps} outside the allowed range [1, inf)")
        if is_concrete(self.t_end) and not float(self.t_end) > self.t_start:
            raise ParameterError(
                f"t_end = {float(self.t_end):g} s must be greater than t_start = {self.t_start:g} s"
            )


def settings(t_end, **kwargs) -> Settings:
    """Build :class:`Settings` with ``t_end`` [s] as a float64 array leaf."""
    return Settings(t_end=jnp.asarray(t_end, dtype=float), **kwargs)
