"""Errors raised by jaxclear, the range checks that produce them, and the run status
enumeration :class:`RESULTS`.

Every check names the parameter, the value it got and the range it allows, so that a
user reading the message knows what to change. Checks run where objects are built
(concrete Python/NumPy values); values that are JAX tracers (inside ``jit``, ``vmap`` or
``grad``) are skipped there and guarded at run time with :func:`equinox.error_if`.
"""

from __future__ import annotations

import difflib
import numbers
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


class JaxclearError(ValueError):
    """Base class of every error jaxclear raises on bad input or failed runs."""


class ParameterError(JaxclearError):
    """A numeric parameter lies outside its physical range."""


class FitDataError(ParameterError):
    """A fit cannot treat its record honestly: non-finite or absurd samples, no signal, or a loss
    at the start values that is zero or not finite (the message names the record)."""


class DesignError(ParameterError):
    """A design problem that cannot be solved honestly: the objective or a constraint is not
    finite at the start design, or a design variable or option is unusable (the message names it)."""


class MechanismError(JaxclearError):
    """The mechanism is malformed: unknown names, redundant or missing constraints."""


class InitialConditionError(JaxclearError):
    """No consistent initial configuration could be computed."""


class SolverError(JaxclearError):
    """The integration failed (step limit, non-finite state)."""


class OutputLockedError(JaxclearError):
    """Another process holds the output folder of a sweep or fit."""


class CheckpointError(JaxclearError):
    """A checkpoint file exists but cannot be read."""


class MissingExtraError(JaxclearError, ImportError):
    """A feature needs an optional extra of ``pyproject.toml`` that is not installed (raised by
    :func:`jaxclear._extras.require_extra` before any work; the message gives the ``pip install``
    line). Also an :class:`ImportError`, so ``except ImportError`` catches it."""


class RESULTS(eqx.Enumeration):
    """Status of a run, as an :class:`equinox.Enumeration` (the pattern of diffrax's and
    optimistix's ``RESULTS``): traceable, batchable, and usable with ``RESULTS.where`` and
    ``result.error_if``. The one status family of jaxclear: :attr:`Solution.status
    <jaxclear.Solution.status>`, a sweep's ``status`` column, a design's journal and
    :attr:`LyapunovResult.status <jaxclear.chaos.LyapunovResult.status>` hold its integer code
    (0 = ok, in the order below; new members are only ever appended, so a code written to a file
    keeps its meaning); :data:`STATUS` maps codes to messages, and
    :func:`jaxclear.integrate.raise_for_status` raises for any of them.

    What a driver concludes about its own optimisation or sample (a fit's ``stop_reason``, a
    design's ``status`` word such as ``converged`` or ``max_iter``, a posterior's ``converged``)
    is not a status of a run: it is never an array, never traced and never raised, so it is a
    word of the driver's report, not a member here."""

    successful = "ok"
    max_steps_reached = "the solver reached max_steps before t_end"
    nonfinite_state = "non-finite state (singular constraint Jacobian, lock-up, or diverging contact)"
    solver_failed = "the solver failed (step size underflow or another diffrax error)"
    assembly_failed = "the initial configuration could not be assembled (Newton did not converge)"
    invalid_restitution = "invalid parameter: restitution must be finite and in (0, 1]"
    invalid_stiffness = "invalid parameter: contact stiffness (K, E*, foundation modulus) must be finite and > 0"
    invalid_clearance = (
        "invalid parameter: radii must be finite and > 0 with journal_radius < bearing_radius "
        "(clearance c = R_B - R_J in (0, R_B)); a slider block must fit its guide (slider_length, "
        "slider_height > 0, slider_height < guide_width)"
    )
    invalid_friction = (
        "invalid parameter: a friction law's number outside its range (coefficient mu_k >= 0, static mu_s >= "
        "mu_k, viscous >= 0, bristle_stiffness sigma_0 > 0, bristle_damping sigma_1 >= 0, all finite)"
    )
    invalid_mass = "invalid parameter: every body's mass and inertia must be finite and > 0"
    invalid_parameter = (
        "invalid parameter: another law or element number outside its range (exponent > 0, "
        "length > 0, impact_velocity_floor > 0, Young's modulus > 0, Poisson ratio in (-1, 0.5), "
        "friction speeds > 0, viscosity > 0, 0 < blend_start < blend_end < 1, slot_length >= 0, "
        "corner_radius > 0, axis non-zero, a spring, damper or bushing constant >= 0, all finite)"
    )
    penetration_too_deep = (
        "penetration deeper than a tenth of the journal radius (of the corner radius in a "
        "translational joint): the contact law is outside its "
        "validity (stiffness far too small, or a lock-up)"
    )
    tangent_overflow = (
        "the tangents overflowed within the shortest renormalisation step (a growth beyond 1e250 within a "
        "millionth of the interval): the tangent dynamics is not resolved (check the run's steps and tolerances)"
    )
    invalid_tolerance = (
        "invalid parameter: the integration tolerances must be finite with rtol in (0, 1) and atol > 0 "
        "(Settings.rtol, Settings.atol)"
    )


STATUS = {int(item._value): RESULTS[item] for item in (getattr(RESULTS, n) for n in RESULTS._name_to_item)}
"""Status code of a run (``Solution.status``) -> its message; code ``i`` is the ``i``-th entry of :class:`RESULTS`."""

#: What a user can do about each failure (appended to the error raised with ``throw=True``).
REMEDIES = {
    1: "raise Settings.max_steps (now {max_steps}, allowed >= 1) or loosen rtol/atol",
    4: "improve the bodies' position guesses (Body.position)",
    11: "raise the contact stiffness (or the materials' Young's modulus) to a physical value",
}


def status_message(code: int, **context) -> str:
    """Message of a status code, with its remedy if there is one (``context`` fills the
    remedy's fields, e.g. ``max_steps``)."""
    message = STATUS.get(int(code), f"unknown status {int(code)}")
    remedy = REMEDIES.get(int(code))
    if remedy is None:
        return message
    return f"{message}; {remedy.format_map(dict({'max_steps': '?'}, **context))}"


def function_name(fn) -> str:
    """``'name' (file.py:line)`` of a user's Python function (through :func:`functools.partial`)
    for a message that names it; the name alone where its source is not found."""
    import inspect
    import os

    fn = getattr(fn, "func", fn)
    name = repr(getattr(fn, "__qualname__", None) or type(fn).__name__)
    try:
        return f"{name} ({os.path.basename(inspect.getsourcefile(fn))}:{inspect.getsourcelines(fn)[1]})"
    except (TypeError, OSError):
        return name


def closest(name: str, candidates, listing: str) -> str:
    """What follows the message of a name that was not found: the closest of ``candidates``
    first (:func:`difflib.get_close_matches`), then how many there are and where to list them
    (``listing``, e.g. ``jc.params.names(mech)``): ``"; did you mean 'clearance'? (40 names:
    jc.params.names(mech))"``. The one format of an unknown name here."""
    candidates = list(candidates)
    near = difflib.get_close_matches(name, candidates, n=3, cutoff=0.6)
    if not near and ":" in name:  # a misspelt base with a valid suffix: mas:rod -> mass:rod
        near = difflib.get_close_matches(name.split(":", 1)[0], candidates, n=3, cutoff=0.6)
    said = ", ".join(repr(n) for n in near[:-1]) + (" or " if len(near) > 1 else "") + (repr(near[-1]) if near else "")
    return (f"; did you mean {said}?" if near else "") + f" ({len(candidates)} names: {listing})"


def is_concrete(value) -> bool:
    """True if no leaf of ``value`` is a JAX tracer (so it can be checked eagerly)."""
    leaves = jax.tree_util.tree_leaves(value)
    return not any(isinstance(x, jax.core.Tracer) for x in leaves)


def check_range(
    name: str,
    value,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
):
    """Raise :class:`ParameterError` unless every element of ``value`` is finite and in range.

    ``low_open``/``high_open`` make the bound exclusive. Tracers are not checked (see module
    docstring). Returns ``value`` unchanged.
    """
    if value is None or not is_concrete(value):
        return value
    arr = np.asarray(value, dtype=float)
    lo = "-inf" if low is None else f"{low:g}"
    hi = "inf" if high is None else f"{high:g}"
    interval = f"{'(' if (low is None or low_open) else '['}{lo}, {hi}{')' if (high is None or high_open) else ']'}"
    u = f" {unit}" if unit else ""
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite, got {value!r}; allowed range {interval}{u}")
    bad = np.zeros(arr.shape, dtype=bool)
    if low is not None:
        bad |= (arr <= low) if low_open else (arr < low)
    if high is not None:
        bad |= (arr >= high) if high_open else (arr > high)
    if np.any(bad):
        shown = arr[bad].ravel()[0]
        raise ParameterError(f"{name} = {shown:g}{u} is outside the allowed range {interval}{u}")
    return value


def check_integer(name: str, value, low: int, high: int | None = None, what: str = "") -> int:
    """``value`` as an ``int`` in ``[low, high]`` (``high`` None: no upper bound), else a
    :class:`ParameterError` that names ``name``, the value and the range."""
    interval = f"[{low}, {high}]" if high is not None else f"[{low}, inf)"
    why = f" ({what})" if what else ""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ParameterError(f"{name} must be an integer in {interval}{why}, got {value!r}")
    if value < low or (high is not None and value > high):
        raise ParameterError(f"{name} = {value} is outside the allowed range {interval}{why}")
    return int(value)


def check_finite(name: str, value):
    """Raise :class:`ParameterError` if ``value`` (concrete) holds NaN or inf."""
    if value is None or not is_concrete(value):
        return value
    if not np.all(np.isfinite(np.asarray(value, dtype=float))):
        raise ParameterError(f"{name} must be finite, got {value!r}")
    return value


def check_vec2(name: str, value, error: type = ParameterError):
    """``value`` as a finite float 2-vector ``[x, y]`` [m]; ``error`` (a :class:`ParameterError`
    by default) naming ``name`` otherwise."""
    import jax.numpy as jnp

    arr = jnp.asarray(value, dtype=float)
    if arr.shape != (2,):
        raise error(f"{name} must be a 2-vector [x, y] in metres, got shape {arr.shape}")
    check_finite(name, arr)
    return arr


# ---- traceable range checks (run time, under jit/vmap) ------------------------------------


def in_range(value, *, low=None, high=None, low_open=False, high_open=False):
    """Traceable counterpart of :func:`check_range`: a boolean scalar, True when every element
    of ``value`` is finite and inside the range (``None`` bounds are open ends). Works on
    tracers, so :func:`jaxclear.simulate` evaluates it at run time under ``jit``/``vmap``."""
    x = jnp.asarray(value, dtype=float)
    ok = jnp.isfinite(x)
    if low is not None:
        ok &= (x > low) if low_open else (x >= low)
    if high is not None:
        ok &= (x < high) if high_open else (x <= high)
    return jnp.all(ok)


class Rule(NamedTuple):
    """One range rule of a number of a body or force element, written once and read two ways:
    traceably at run time (:meth:`ok`, combined by :func:`first_failure` into the status
    ``result``) and, on a concrete object whose run failed that status, eagerly (:meth:`failure`:
    the rule's own message, naming the number, its value and its range, as :func:`check_range`
    says it). ``name`` is what the message calls the number (``"clearance c = R_B - R_J"``)."""

    name: str
    value: Any
    result: RESULTS
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    unit: str = ""

    def ok(self):
        """Traceable: True when the value is finite and in range (:func:`in_range`)."""
        return in_range(self.value, low=self.low, high=self.high, low_open=self.low_open, high_open=self.high_open)

    def failure(self) -> str | None:
        """For a concrete value: the message of :func:`check_range` when the rule fails, else
        ``None``."""
        try:
            check_range(self.name, self.value, low=self.low, high=self.high, low_open=self.low_open,
                        high_open=self.high_open, unit=self.unit)
        except ParameterError as err:
            return str(err)
        return None


def _is_item(check) -> bool:
    return isinstance(check, type(RESULTS.successful))


def failed_check(checks) -> str | None:
    """Eagerly, for concrete values: what fails first among ``checks`` (the sequence an object's
    ``check()`` combines with :func:`first_failure`, in the same order): a :class:`Rule`'s own
    message; for an object with ``check()`` (a law), what fails first among its ``checks()``,
    else its status's message; for a failed :class:`RESULTS` item, its message without the
    ``invalid parameter:`` prefix. ``None`` when all pass."""
    def said(code):
        return STATUS[int(code)].removeprefix("invalid parameter: ")

    for check in checks:
        if isinstance(check, Rule):
            message = check.failure()
            if message is not None:
                return message
        elif isinstance(check, tuple):
            ok, item = check
            if not bool(ok):
                return said(item._value)
        elif _is_item(check):
            if int(check._value) != int(RESULTS.successful._value):
                return said(check._value)
        else:  # an object with its own checks (a contact or friction law, a material)
            message = failed_check(check.checks()) if hasattr(check, "checks") else None
            code = int(check.check()._value)
            if message is not None or code != int(RESULTS.successful._value):
                return message or said(code)
    return None


def first_failure(*checks) -> RESULTS:
    """Combine :class:`Rule` s, ``(ok, RESULTS item)`` pairs, RESULTS items (successful meaning
    ok) and objects with a ``check()`` (a law) into one traceable :class:`RESULTS`: the first
    failing check's item, or ``successful``."""
    result = RESULTS.successful
    for check in reversed(checks):
        if not (isinstance(check, (Rule, tuple)) or _is_item(check)):
            check = check.check()
        if isinstance(check, Rule):
            result = RESULTS.where(check.ok(), result, check.result)
        elif isinstance(check, tuple):
            ok, item = check
            result = RESULTS.where(ok, result, item)
        else:
            result = RESULTS.where(check == RESULTS.successful, result, check)
    return result


def invalid_codes() -> tuple[int, ...]:
    """Status codes of the ``invalid_*`` entries (inputs outside their ranges)."""
    return tuple(code for code, msg in STATUS.items() if msg.startswith("invalid parameter"))
