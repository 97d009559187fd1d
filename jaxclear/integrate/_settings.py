"""How to integrate: the solver, tolerances, output grid, derivatives, output sampling and
contact onsets (:class:`Settings`; the strategy objects of :mod:`.strategies`)."""

from __future__ import annotations

import dataclasses
from typing import Mapping

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import RESULTS, JaxclearError, ParameterError, Rule, failed_check, is_concrete
from .._results import deprecated
from .._types import Array, Float
from ._dynamics import Baumgarte
from ._solvers import UnrolledExplicitRK
from ._strategies import (
    SOLVERS,
    AbstractDerivatives,
    AbstractOnsets,
    AbstractSampling,
    ExactOnsets,
    Sensitivity,
    from_names,
    stages_name,
)

#: Largest number of output samples of one run (``n_out``): ~1 kB per sample of a small
#: mechanism (states, accelerations, reactions, contact outputs) makes this ~2 GB.
MAX_OUT_SAMPLES = 2_000_000

#: Default of ``Settings.continuous_contact_after`` [s].
CONTINUOUS_CONTACT_AFTER = 2e-4


def _tolerance(value):
    """A tolerance as a float64 array leaf: a JAX array (a tracer too) as ``jnp``, a number as a
    NumPy scalar array (building settings compiles nothing; :func:`default_settings`)."""
    if isinstance(value, jax.Array):
        return jnp.asarray(value, dtype=float)
    return np.asarray(value, dtype=np.float64)


class _OldName:
    """An attribute of :class:`Settings` before its strategy objects, kept for one release: read
    on an instance, its old value (a string or number) with a ``DeprecationWarning`` naming the
    new field; read on the class, its old default."""

    def __init__(self, field: str, read, default):
        self.field, self.read, self.default = field, read, default

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self.default
        deprecated(f"Settings.{self.name}", f"Settings.{self.field}", stacklevel=3)  # past equinox's __getattribute__
        return self.read(obj)


class Settings(eqx.Module):
    """How to integrate.

    Attributes:
        t_end: end time [s] (array leaf: may be swept).
        t_start: start time [s] (default 0).
        n_out: number of output samples on the uniform grid ``[t_start, t_end]`` (default 1001).
        solver: a diffrax Runge-Kutta solver instance (default ``diffrax.Tsit5()``); a name of
            :data:`~.strategies.SOLVERS` is accepted. Its stages run in diffrax's stage loop; an explicit
            solver in :class:`~jaxclear.integrate.UnrolledExplicitRK` runs them unrolled
            (the same step; ``stages="unrolled"``).
        rtol, atol: tolerances of the adaptive PID step controller (relative [-], absolute [SI];
            defaults 1e-6, 1e-9); float64 array leaves, so that a run at another tolerance is the
            same compiled program with other inputs (a tolerance study compiles once).
        dt0: first step [s]; ``None`` (default) lets diffrax choose.
        dtmax: largest step [s] or ``None`` (default).
        max_steps: step limit (default 400,000); reaching it is an error (or status 1 with
            ``throw=False``).
        baumgarte: stabilization gains (alpha, beta) [1/s] (default 5, 5).
        derivatives: how derivatives of the run are computed: :class:`~.strategies.Sensitivity`
            (default; the error-controlled forward sensitivities, ``tolerance`` 0.1) or
            :class:`~.strategies.ThroughLoop` (JAX's derivative through diffrax's loop with
            its ``adjoint``: ``"recursive"`` with ``checkpoints``, ``"forward"``, ``"direct"``).
        throw: raise errors (True, default) or report them in ``Solution.status`` (False;
            sweeps).
        progress: show a progress bar while integrating (default False).
        continuous_contact_after: a contact lasting longer than this [s] is classed as
            continuous contact (mode 2) instead of impact (mode 1) (default 2e-4).
        allow_free_dof: a driven mechanism normally has all its motion determined by the
            drivers (plus the journal's freedom); True allows additional free motion (default
            False).
        output: how the output samples are written: :class:`~.strategies.SampleLoop`
            (default; diffrax's saving) or :class:`~.strategies.SampleBlock` (a step's samples at
            once).
        onsets: contact onsets: :class:`~.strategies.ExactOnsets` (default; the step that
            crosses into contact ends just past the onset) or :class:`~.strategies.StepOnsets`.

    The defaults' measurements (stage loop against unrolled stages, the two samplings, the
    sensitivities' tolerance): ``benchmarks/README.md``, "Settings' measured choices".

    The keywords of before the strategy objects are still accepted and converted
    (:func:`~jaxclear.integrate.from_names`): ``adjoint`` (``"sensitivity"``,
    ``"recursive"``, ``"forward"``, ``"direct"``), ``derivative_tolerance``, ``checkpoints``,
    ``stages`` (``"loop"``, ``"unrolled"``), ``exact_onsets`` (bool), ``sampling`` (``"loop"``,
    ``"block"``); each replaces its part of the field it now belongs to (so
    ``dataclasses.replace(s, adjoint="forward")`` works). Reading them (``s.adjoint``, ...) gives
    the old value with a ``DeprecationWarning``, for one release.
    """

    t_end: Float[Array, ""]
    t_start: float = eqx.field(static=True)
    n_out: int = eqx.field(static=True)
    solver: diffrax.AbstractSolver = eqx.field(static=True)
    rtol: Float[Array, ""]
    atol: Float[Array, ""]
    dt0: float | None = eqx.field(static=True)
    dtmax: float | None = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    baumgarte: Baumgarte
    derivatives: AbstractDerivatives = eqx.field(static=True)
    throw: bool = eqx.field(static=True)
    progress: bool = eqx.field(static=True)
    continuous_contact_after: float = eqx.field(static=True)
    allow_free_dof: bool = eqx.field(static=True)
    output: AbstractSampling = eqx.field(static=True)
    onsets: AbstractOnsets = eqx.field(static=True)

    def __init__(self, t_end, t_start=0.0, n_out=1001, solver="tsit5", rtol=1e-6, atol=1e-9, dt0=None, dtmax=None,
                 max_steps=400_000, baumgarte=None, derivatives=None, throw=True, progress=False,
                 continuous_contact_after=CONTINUOUS_CONTACT_AFTER, allow_free_dof=False, output=None, onsets=None, *,
                 adjoint=None, derivative_tolerance=None, checkpoints=None, stages=None, exact_onsets=None,
                 sampling=None):
        self.t_end = t_end
        self.t_start = t_start
        self.n_out = n_out
        self.rtol, self.atol = _tolerance(rtol), _tolerance(atol)
        self.dt0 = dt0
        self.dtmax = dtmax
        self.max_steps = max_steps
        self.baumgarte = Baumgarte(jnp.asarray(5.0), jnp.asarray(5.0)) if baumgarte is None else baumgarte
        self.throw = throw
        self.progress = progress
        self.continuous_contact_after = continuous_contact_after
        self.allow_free_dof = allow_free_dof
        self.solver, self.derivatives, self.output, self.onsets = from_names(
            solver, derivatives, output, onsets, adjoint=adjoint, derivative_tolerance=derivative_tolerance,
            checkpoints=checkpoints, stages=stages, exact_onsets=exact_onsets, sampling=sampling)

    # the names of before the strategy objects, for one release
    adjoint = _OldName("derivatives", lambda s: s.derivatives.name, "sensitivity")
    derivative_tolerance = _OldName(
        "derivatives", lambda s: getattr(s.derivatives, "tolerance", Sensitivity().tolerance), Sensitivity().tolerance)
    checkpoints = _OldName("derivatives", lambda s: getattr(s.derivatives, "checkpoints", None), None)
    stages = _OldName("solver", lambda s: stages_name(s.solver), "loop")
    exact_onsets = _OldName("onsets", lambda s: isinstance(s.onsets, ExactOnsets), True)
    sampling = _OldName("output", lambda s: s.output.name, "loop")

    def __check_init__(self):
        for rule in tolerance_rules(self):
            if jnp.shape(rule.value) != ():
                raise ParameterError(f"{rule.name} must be one number, not an array of shape {jnp.shape(rule.value)}")
        failed = failed_check(tolerance_rules(self)) if is_concrete((self.rtol, self.atol)) else None
        if failed is not None:
            raise ParameterError(failed)
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


def tolerance_rules(s: Settings) -> tuple:
    """The range rules of ``s.rtol`` in (0, 1) and ``s.atol`` in (0, inf), status
    ``invalid_tolerance``: checked eagerly when ``Settings`` is built with concrete tolerances and
    in the run (:func:`~jaxclear._errors.first_failure`), where traced ones (a ``jax.vmap`` over
    them) are seen."""
    return (Rule("rtol", s.rtol, RESULTS.invalid_tolerance, low=0.0, high=1.0, low_open=True, high_open=True),
            Rule("atol", s.atol, RESULTS.invalid_tolerance, low=0.0, low_open=True))


def settings(t_end, **kwargs) -> Settings:
    """Build :class:`Settings` with ``t_end`` [s] as a float64 array leaf."""
    return Settings(t_end=jnp.asarray(t_end, dtype=float), **kwargs)


# ---------------------------------------------------------------------------------------------
# Settings as text (the command line, a [settings] table) and the drivers' old keywords

#: The fields of :class:`Settings` written by name where settings are text: the command line's
#: integration options (:func:`jaxclear.cli.settings.add_settings_options`) and the ``[settings]``
#: table of a sweep or tolerance-study file; :func:`settings_from_options` converts them.
#: ``derivatives`` is a name of :data:`~.strategies.ADJOINTS`, ``output`` of
#: :data:`~.strategies.OUTPUTS`, ``onsets`` of :data:`~.strategies.ONSETS`, ``solver`` of
#: :data:`~.strategies.SOLVERS`; ``derivative_tolerance`` is :class:`~.strategies.Sensitivity`'s
#: ``tolerance``, ``checkpoints`` :class:`~.strategies.ThroughLoop`'s.
OPTION_KEYS = ("solver", "rtol", "atol", "dt0", "dtmax", "max_steps", "derivatives", "derivative_tolerance",
               "checkpoints", "output", "onsets", "continuous_contact_after", "allow_free_dof")
_OPTION_TYPES = {"solver": str, "rtol": float, "atol": float, "dt0": float, "dtmax": float, "max_steps": int,
                 "derivatives": str, "derivative_tolerance": float, "checkpoints": int, "output": str, "onsets": str,
                 "continuous_contact_after": float, "allow_free_dof": bool}


def _option(source: str, key: str, value):
    kind = _OPTION_TYPES[key]
    if value is None and key in ("dt0", "dtmax", "checkpoints"):
        return None
    if kind is bool:
        ok = isinstance(value, bool)
    elif kind is str:
        ok = isinstance(value, str)
    else:
        ok = not isinstance(value, bool) and isinstance(value, (int, float)) and (kind is float or float(value) == int(value))
    if not ok:
        raise ParameterError(f"{source}: {key} = {value!r}: expected {'an integer' if kind is int else 'a number' if kind is float else 'true or false' if kind is bool else 'a name'}")
    return kind(value)


def settings_from_options(options: Mapping, base: Settings | None = None, *, source: str = "settings") -> Settings:
    """``base`` (default: ``Settings`` with its defaults, ``t_end`` 1 s) with the fields of
    ``options`` replaced, each given by name (:data:`OPTION_KEYS`, the command line's and the
    files' spelling): the one conversion of the integration options written as text, through
    :class:`Settings` itself (names to strategy objects:
    :func:`~jaxclear.integrate.from_names`). A key outside :data:`OPTION_KEYS`, a
    value of the wrong kind or outside its range is a :class:`~jaxclear.ParameterError`
    beginning with ``source``."""
    unknown = sorted(set(options) - set(OPTION_KEYS))
    if unknown:
        raise ParameterError(f"{source}: unknown key(s) {unknown}; allowed: {list(OPTION_KEYS)}")
    changes = {key: _option(source, key, value) for key, value in options.items()}
    base = Settings(t_end=jnp.asarray(1.0)) if base is None else base
    if "derivative_tolerance" in changes and "derivatives" not in changes and base.derivatives.name != "sensitivity":
        changes["derivatives"] = "sensitivity"  # a tolerance asks for the sensitivities
    try:
        return dataclasses.replace(base, **changes)
    except JaxclearError as err:
        raise ParameterError(f"{source}: {err}") from None


def solver_name(solver) -> str:
    """The name in :data:`~.strategies.SOLVERS` of a solver instance (its ``repr`` for another
    solver)."""
    inner = solver.solver if isinstance(solver, UnrolledExplicitRK) else solver
    return next((name for name, cls in SOLVERS.items() if type(inner) is cls), repr(inner))


def option_values(s: Settings) -> dict:
    """The fields of ``s`` by name (:data:`OPTION_KEYS`): what :func:`settings_from_options`
    reads, what a driver records of its runs' settings, and the defaults the command line shows
    (read from ``Settings`` itself, never repeated)."""
    return {"solver": solver_name(s.solver), "rtol": float(s.rtol), "atol": float(s.atol), "dt0": s.dt0, "dtmax": s.dtmax,
            "max_steps": s.max_steps, "derivatives": s.derivatives.name,
            "derivative_tolerance": getattr(s.derivatives, "tolerance", None),
            "checkpoints": getattr(s.derivatives, "checkpoints", None), "output": s.output.name,
            "onsets": s.onsets.name, "continuous_contact_after": s.continuous_contact_after,
            "allow_free_dof": s.allow_free_dof}


def default_settings() -> Settings:
    """``Settings`` with every default (``t_end`` 1 s): the base of a driver given no settings,
    and what the command line shows as its defaults. Its array leaves are NumPy values, so that
    building it compiles nothing (the first ``jnp`` array of a process compiles a small program:
    ``jaxclear presets`` and ``--help`` compile nothing); a driver's runs take them as any array."""
    return Settings(t_end=np.asarray(1.0), baumgarte=Baumgarte(np.asarray(5.0), np.asarray(5.0)))


def deprecated_keywords(driver: str, settings: Settings | None, stacklevel: int = 3, **given) -> dict:
    """The old integration keywords a driver was given (``rtol=``, ``atol=``, ``solver=``,
    ``max_steps=``: those not None), for the driver to replace in its settings, for one release:
    alone, a ``DeprecationWarning`` naming the replacement ``settings=jc.settings(...)``
    (``stacklevel``: as :func:`warnings.warn`'s, counted from this function: 3 is the caller of
    the driver that calls it); with ``settings`` too, a :class:`~jaxclear.ParameterError`
    naming both."""
    given = {key: value for key, value in given.items() if value is not None}
    if not given:
        return {}
    keywords = ", ".join(f"{key}=" for key in given)
    spelled = ", ".join(f"{key}={value!r}" for key, value in given.items())
    if settings is not None:
        raise ParameterError(f"{driver}: both settings= and {keywords} given; give the settings only, e.g. "
                             f"settings=jc.settings(t_end, {spelled}) (t_end and n_out are the driver's own)")
    deprecated(f"{driver}({keywords}...)", f"settings=jc.settings(t_end, {spelled}) (t_end and n_out are the "
               "driver's own)", stacklevel=stacklevel)
    return given


def settings_or_default(driver: str, settings: Settings | None, base: Settings, stacklevel: int = 4,
                        **old) -> Settings:
    """A driver's settings: ``settings`` (:func:`check_settings`), else ``base`` (the driver's own
    default) with the deprecated keywords ``old`` replaced (:func:`deprecated_keywords`: a
    ``DeprecationWarning``; with ``settings`` too, a :class:`~jaxclear.ParameterError`); a bad
    value among them is a ``ParameterError`` naming the driver. ``stacklevel``: as
    :func:`deprecated_keywords`' for a driver that calls a helper that calls this (the fit's and
    the statistics fit's)."""
    old = deprecated_keywords(driver, settings, stacklevel=stacklevel + 1, **old)
    if check_settings(driver, settings) is not None:
        return settings
    try:
        return dataclasses.replace(base, **old)
    except JaxclearError as err:
        raise ParameterError(f"{driver}: {err}") from None


def check_settings(driver: str, settings, required: bool = False, name: str = "settings") -> Settings | None:
    """``settings`` as a run or driver takes it: a :class:`Settings`, or None (the driver's own)
    where not ``required``; else a :class:`~jaxclear.ParameterError` naming the driver, the
    argument ``name`` and the expected type (a check of types only: it holds inside ``jit`` and
    ``vmap``, where the settings' structure is static). The one check of every ``settings=``
    (simulate, sensitivities, fit, posterior, statistics fit, sweep, tolerance study, Lyapunov
    exponents)."""
    if settings is None and required:
        raise ParameterError(f"{driver}: settings are required (the run's span [t_start, t_end]): "
                             f"{name}=jc.settings(t_end, ...)")
    if settings is not None and not isinstance(settings, Settings):
        raise ParameterError(f"{driver}: {name} = {settings!r}: expected a jaxclear.Settings "
                             "(jc.settings(t_end, rtol=...))" + ("" if required else " or None"))
    return settings
