r"""Whether a fit's estimates are a result: :func:`assess` lists why they are not.

A least-squares fit always ends somewhere. On a chaotic record it can end on an estimate that
no physical joint has (a stiffness of 1.8e14 N/m^1.5 where steel on steel at the benchmark's
radii gives 6.6e10), at the bound of its transform (restitution 0 or 1), with the sensor gain
carrying the signal's scale (0.009), or with a standard deviation many times the estimate. Such
an end is reported as a **failed** fit: :attr:`FitResult.failures <jaxclear.fitting.FitResult>`
holds one sentence per broken rule (the parameter, its value, the rule and what to try),
``FitResult.ok`` is False, ``fit.json`` says ``"ok": false`` and ``jaxclear fit --strict``
exits with status 3. The rules (thresholds: the module constants below):

* **bound of the transform**: a ``logit`` parameter (restitution) within
  :data:`LOGIT_EDGE_DISTANCE` of 0 or 1; a ``log`` parameter more than a factor
  :data:`LOG_RUN_FACTOR` from its start (unless a physical range, below, vouches for it); any
  mechanism parameter outside its range in :mod:`jaxclear.params` (a clearance not below the
  bearing radius, a value that under- or overflowed to 0 or infinity);
* **physical stiffness**: a contact stiffness outside the range the law's own stiffness
  formula (:meth:`~jaxclear.contact.base.AbstractNormalLaw.stiffness_value` with the stiffness
  leaf ``None``: :func:`~jaxclear.contact.hertz.cylindrical_stiffness` for the Hertz family)
  gives for the joint's radii with any pair of materials of Young's modulus in
  [:data:`YOUNG_MIN`, :data:`YOUNG_MAX`] and Poisson ratio in [:data:`POISSON_MIN`,
  :data:`POISSON_MAX`] (:func:`stiffness_range`);
* **sensor gain** outside [:data:`GAIN_MIN`, :data:`GAIN_MAX`];
* **standard deviation** not finite, or larger than :data:`STD_RATIO` times the estimate of a
  positive parameter (``log`` or ``logit`` transform: stiffness, restitution, masses, ...);
* **window residual**: with several windows and the noise level given, a window whose residual
  is above the noise by more than :data:`NOISE_Z` chi-square std (its start not found);
* **residual**: lag-1 autocorrelation above :data:`RESIDUAL_AUTOCORRELATION` (above
  :data:`FREE_START_AUTOCORRELATION` with every window's start free) with a normalised misfit
  above :data:`RESIDUAL_LOSS`: the model does not follow the record;
* **not converged with free starts**: a fit of a record that begins mid-run (every window's
  start free) whose last stage stopped on ``max_iter``: the joint problem of parameters and
  starts is rugged, and on a record of the independent simulator such a fit followed the record
  to its noise with the stiffness 13 % and the restitution 7 std off;
* **starts that disagree**: with several starts, two whose first-stage losses are within
  :data:`START_LOSS_TOLERANCE` of the best and whose estimates differ by more than
  :data:`START_STD_SPREAD` standard deviations (and by :data:`START_MIN_SPREAD` in the
  transformed coordinate): "estimates change with the start".

:func:`assess` is pure (no simulation; a few scalar evaluations of the stiffness formula), so
it runs when a :class:`~jaxclear.fitting.FitResult` is made; docs/theory/fit.md ("When a fit
fails") tabulates the causes and what to try.
"""

from __future__ import annotations

import itertools
import math
import re
from typing import Iterable, Sequence

import equinox as eqx

from .. import params
from .._errors import JaxclearError
from ..contact.base import Material
from ..model import Mechanism
from .parameters import SENSOR_PARAMETERS, to_z, transform

#: Distance of a restitution-like (``logit``) estimate from 0 or 1 that counts as "at the bound"
#: (``|logit| > 6.9``): measured coefficients of restitution of engineering contacts lie within
#: about 0.05 to 0.98, and the optimiser only gets this close to a bound by running into it.
LOGIT_EDGE_DISTANCE = 1e-3
#: Factor between a ``log`` parameter's estimate and its start beyond which the fit ran down its
#: log transform (towards 0 or infinity) rather than to an optimum: starts are spread by a factor
#: 3 and a sensible start is within a factor 10 to 30 of the truth.
LOG_RUN_FACTOR = 1e3
#: Softest Young's modulus of a joint material [Pa]: 1 GPa, polymers (PE, nylon about 1-3 GPa).
YOUNG_MIN = 1e9
#: Stiffest Young's modulus of a joint material [Pa]: 1000 GPa, tungsten carbide (about 600-700
#: GPa) with a margin.
YOUNG_MAX = 1000e9
#: Smallest Poisson ratio of a joint material [-]: 0.2 (ceramics, carbides).
POISSON_MIN = 0.2
#: Largest Poisson ratio of a joint material [-]: 0.45 (polymers).
POISSON_MAX = 0.45
#: Plausible range of a fitted accelerometer gain [-]: a calibrated sensor is within a few percent
#: of 1; a gain a factor 2 away means the model cannot reproduce the signal's scale (wrong units,
#: wrong model) and the gain absorbed it.
GAIN_MIN, GAIN_MAX = 0.5, 2.0
#: Standard deviation of a positive parameter, as a multiple of its estimate, beyond which the
#: record does not determine it: the 1-sigma interval then reaches 0 (Gauss-Newton, delta method).
STD_RATIO = 1.0
#: Relative first-stage loss above the best start's within which another start counts as equally
#: good: the start stage stops on a relative loss decrease of 1e-3 (plan.Stage.ftol), so losses
#: 1 % apart cannot be told apart by it.
START_LOSS_TOLERANCE = 0.01
#: Difference of two equally good starts' estimates, in standard deviations of the result, that
#: is more than noise: 5 sigma.
START_STD_SPREAD = 5.0
#: ... and in the transformed coordinate (10 % of a log parameter, 0.1 in logit restitution, 0.1
#: data RMS of the bias; 10 % of the value for an untransformed one): starts that converge to one
#: minimum of the first (short, coarse) stage differ by a few percent there, while distinct minima
#: of the chaotic loss lie tens of percent apart.
START_MIN_SPREAD = 0.1
#: Exponent of the Hertz family for which the stiffness formulas hold [-] (N/m^1.5).
HERTZ_EXPONENT = 1.5

_START_STAGE = re.compile(r"^start (\d+)/(\d+)\b")


def assess(free: Sequence[str], estimates: dict, std: dict, *, start: dict | None = None,
           mech: Mechanism | None = None, history: Iterable[dict] = (), scale: float = 1.0,
           autocorrelation: float | None = None, loss: float | None = None, stop_reason: str = "",
           free_start: bool = False, profiles: dict | None = None,
           noise: tuple | None = None, windows: tuple | None = None) -> tuple[str, ...]:
    """The reasons a fit's estimates are not a result; ``()`` when they are.

    Args:
        free: the fitted parameter names (:mod:`jaxclear.params` names, ``sensor_gain``,
            ``sensor_bias``).
        estimates, std: name -> estimate and its standard deviation (SI; the stiffness in the
            law's unit, N/m^1.5 for the Hertz family).
        start: name -> start value of the fit (SI); without it the run-off rule is skipped.
        mech: the fitted mechanism (its geometry and laws; the free values are taken from
            ``estimates``); without it the physical stiffness range and the clearance's bearing
            radius are not checked.
        history: the fit's iteration records (``FitResult.history``: ``stage``, ``loss``,
            ``values``); the last record of each ``start j/N`` stage is that start's result.
        scale: the data RMS [m/s^2] (``sensor_bias``'s transformed coordinate is bias / scale).
        autocorrelation, loss: the residual's lag-1 autocorrelation and the normalised misfit
            (``FitResult.residual_autocorrelation``, ``FitResult.loss``); without them the
            residual rule is skipped.
        stop_reason, free_start: the last stage's stop reason and whether every window's start
            was free (``start_state="free"``): a free-start fit that stopped on ``max_iter`` fails.
        profiles: name -> its profile likelihood (``FitResult.profiles``): a side that stays
            open fails the name (the record does not bound it; the std rules then judge the
            Gauss-Newton std), a point that fits better than the estimate (still, after the
            fit began again from such a point: :data:`~jaxclear.fitting.profile.RESTARTS`) fails
            the fit.
        noise: ``(sigma_fit, sigma_given, dof)``: the residual's std [record units], the
            sensor's noise level given by the user (None: unknown, no test) and the residual's
            degrees of freedom (samples minus unknowns): a residual above the noise by more
            than :data:`NOISE_Z` chi-square std fails the fit.
        windows: ``(sigmas, dofs)`` per fit window (several windows, the noise level given):
            each window's residual std [record units] and degrees of freedom; a window above
            the noise by more than :data:`NOISE_Z` chi-square std fails the fit.

    Returns:
        One sentence per broken rule (module docstring), in ``free`` order, then the starts.
    """
    start = start or {}
    fitted = _with_estimates(mech, free, estimates)
    out: list[str] = []
    profiles = profiles or {}
    for name in free:
        sd = std.get(name, math.nan)
        if name in profiles and not math.isfinite(sd):
            sd = profiles[name]["std_gauss_newton"]
        out += _parameter_failures(name, estimates.get(name, math.nan), sd, start.get(name), fitted)
        if name in profiles:
            out += _profile_failures(name, estimates.get(name, math.nan), profiles[name], _unit(name, fitted))
    out += _start_failures(free, std, history, scale, mech)
    if free_start and stop_reason == "max_iter":
        out.append("the last stage stopped on max_iter before converging, with every window's start free: the "
                   "estimates are not at an optimum of the joint problem; try a larger max_iter (--max-iter), more or "
                   "shorter windows (--windows, --window), or the encoder's crank angle if it was fitted")
    if noise is not None and noise[1] is not None:
        out += _noise_failures(*noise)
        if windows is not None and len(windows[0]) > 1:
            out += _window_failures(*windows, noise[1])
    limit = FREE_START_AUTOCORRELATION if free_start else RESIDUAL_AUTOCORRELATION
    if autocorrelation is not None and loss is not None and autocorrelation > limit and loss > RESIDUAL_LOSS:
        out.append(f"the residual is not noise (lag-1 autocorrelation {autocorrelation:.2f} > "
                   f"{limit:g}, normalised misfit {loss:.3g}): the model does not follow the record, "
                   "so the estimates and their std describe a misfit; try: for a record that begins mid-run "
                   "start_state='free' (--start-state free) with the encoder's crank angle, the sensor's filter "
                   "(cut-off, order) and delay, more or shorter windows, other start values")
    return tuple(out)


#: Chi-square standard deviations by which the residual's variance may exceed the given noise's.
#: With the noise level known (a record of the machine at rest), ``dof s^2 / sigma^2`` is
#: chi-square with ``dof`` degrees of freedom for a model that follows the record, so
#: ``z = (s^2 / sigma^2 - 1) / sqrt(2 / dof)`` is about standard normal. A fit of a record of the
#: independent simulator that began mid-run passed every other rule with the stiffness 11.8 % low
#: (6 std) and a residual std 1.12 times the noise's over 539 degrees of freedom (z = 4.3).
NOISE_Z = 3.0


def _above_noise(sigma: float, sigma_given: float, dof: float) -> tuple[float, float]:
    """``(ratio, z)``: the residual's variance over the noise's, and by how many chi-square std
    it lies above it, ``z = (s^2 / sigma^2 - 1) / sqrt(2 / dof)`` (:data:`NOISE_Z`)."""
    ratio = (sigma / sigma_given) ** 2
    return ratio, (ratio - 1.0) / math.sqrt(2.0 / dof)


def _noise_failures(sigma_fit: float, sigma_given: float, dof: int) -> list:
    """The failure of a residual above the given noise level (:data:`NOISE_Z`)."""
    if not (math.isfinite(sigma_fit) and dof > 0):
        return []
    ratio, z = _above_noise(sigma_fit, sigma_given, dof)
    if z <= NOISE_Z:
        return []
    return [f"the residual's std {sigma_fit:.4g} is {math.sqrt(ratio):.3g} times the sensor's noise {sigma_given:.4g} "
            f"given (noise_sigma; {z:.1f} chi-square std over {dof} degrees of freedom, more than {NOISE_Z:g}): the "
            "model does not follow the record to its noise, so the estimates describe a misfit; for a record that "
            "begins mid-run a window's start may not have been found: try more or shorter windows (--windows, "
            "--window), other start values, --starts N; check the sensor model and the noise level"]


def _window_failures(sigmas: Sequence[float], dofs: Sequence[float], sigma_given: float) -> list:
    """The failure of windows whose residual is above the given noise level by more than
    :data:`NOISE_Z` chi-square std each (the test of :func:`_noise_failures`, window by window).
    A window whose start lies in another basin leaves its misfit in that window alone, and over
    the whole record it can pass: on acceptance record 1 of the independent simulator the fit's
    residual std was 1.05 times the noise over all four windows while window 1's was 1.33 times
    it (its second half not followed), with the restitution 0.93 for a true 0.75, 16 std off."""
    bad = []
    for k, (sigma, dof) in enumerate(zip(sigmas, dofs)):
        if not (math.isfinite(sigma) and dof > 0):
            continue
        ratio, z = _above_noise(sigma, sigma_given, dof)
        if z > NOISE_Z:
            bad.append(f"{k + 1} ({math.sqrt(ratio):.3g} times, {z:.1f} chi-square std over {dof:.0f} degrees of "
                       "freedom)")
    if not bad:
        return []
    return [f"the residual of window{'s' if len(bad) > 1 else ''} {'; '.join(bad)} is above the sensor's noise "
            f"given (noise_sigma; more than {NOISE_Z:g} chi-square std): the model does not follow "
            f"{'these windows' if len(bad) > 1 else 'this window'}, so the estimates describe a misfit; for a record "
            "that begins mid-run the window's start was probably not found: try more or shorter windows (--windows, "
            "--window), --starts N, other start values"]


def _profile_failures(name: str, value: float, profile: dict, unit: str) -> list:
    """The failures a profile likelihood shows (:mod:`jaxclear.fitting.profile`)."""
    out = []
    better = profile.get("better")
    if better is not None:
        out.append(f"the profile likelihood of {name} found a better fit at {better['value']:.6g}{unit} (its loss "
                   f"{-better['deviance']:.3g} noise variances below the estimate {value:.6g}{unit}'s): the fit stopped "
                   f"in a local minimum; fit again from start={{{name!r}: {better['value']:.6g}}} (--start "
                   f"{name}={better['value']:.6g}) or with more starts (--starts N)")
    if profile.get("open"):
        out.append(f"{name} = {value:.6g}{unit}: its profile likelihood does not close at the 90 % level "
                   f"({'; '.join(profile['open'])}): the record does not determine it; free fewer parameters (fix the "
                   "known ones), or fit a longer window or more windows (--windows N) holding more impacts")
    return out


#: Lag-1 autocorrelation of the residual above which the model does not follow the record: white
#: noise gives about 0 (+-2/sqrt(N)), the fit warns from 0.3; at 0.5 most of the misfit is a
#: smooth signal the model lacks (an outside check saw 0.76-0.96 on every failed fit of records
#: that begin mid-run; a fit of such a record here ended at 0.80 with the stiffness 68 % and the
#: restitution 51 std off).
RESIDUAL_AUTOCORRELATION = 0.5
#: The same with every window's start free (a record that begins mid-run): the starts are many
#: unknowns that can absorb a smooth misfit, so the rule is stricter. On records of the
#: independent simulator the residual at the true values and starts is white (the sensor's noise
#: is added after its filter; a fit that found the motion ended at 0.003), while a fit with the
#: restitution 0.863 for 0.75 (108 std off) and a misfit twice the noise's left 0.30. With
#: ``N`` fitted samples (2400 on four 3 ms windows at 50 kHz) white noise gives ``+-1/sqrt(N)``,
#: 0.02: 0.2 is ten of those. A sensor whose noise passes its own low-pass (coloured noise) shows
#: a residual correlated at lag 1 even at the truth: compare with the lag-1 autocorrelation of a
#: record of the machine at rest (its noise alone) before trusting or rejecting such a fit.
FREE_START_AUTOCORRELATION = 0.2
#: Normalised misfit (mean square residual / mean square record) below which the residual rule
#: does not apply: a model within 1 % RMS of the record (a noise-free record's misfit is
#: correlated rounding) is a result whatever its autocorrelation.
RESIDUAL_LOSS = 1e-4


def stiffness_range(mech: Mechanism, name: str = "stiffness") -> tuple[float, float, str, str] | None:
    """``(low, high, unit, what)``: the range of the contact stiffness ``name`` (``stiffness``
    or ``stiffness@J``) that the law's own formula gives for the joint's radii and any two
    materials of Young's modulus (Pa) in [:data:`YOUNG_MIN`, :data:`YOUNG_MAX`] and Poisson
    ratio in [:data:`POISSON_MIN`, :data:`POISSON_MAX`] (every combination of the extremes for
    the bearing and the journal); ``what`` describes the joint. None where the law derives no
    stiffness from materials (Kelvin-Voigt, a translational joint without radii) or its exponent
    is not :data:`HERTZ_EXPONENT` (the formula's unit is N/m^1.5)."""
    base, k, _ = params.split_name(name, mech)
    if base != "stiffness" or not 0 <= k < len(mech.clearance_joints):
        return None
    joint = mech.clearance_joints[k]
    law = joint.law
    r_b, r_j = getattr(joint, "bearing_radius", None), getattr(joint, "journal_radius", None)
    leaf = law.stiffness_parameter
    if r_b is None or r_j is None or not all(hasattr(law, f) for f in ("bearing_material", "journal_material", leaf)):
        return None
    modulus = leaf in ("modulus", "foundation_modulus")  # an effective modulus [Pa], not K [N/m^n]
    if not modulus and abs(float(getattr(law, "exponent", math.nan)) - HERTZ_EXPONENT) > 1e-12:
        return None
    values = []
    corners = list(itertools.product((YOUNG_MIN, YOUNG_MAX), (POISSON_MIN, POISSON_MAX)))
    for (e_b, nu_b), (e_j, nu_j) in itertools.product(corners, corners):
        derived = eqx.tree_at(lambda m: (getattr(m, leaf), m.bearing_material, m.journal_material), law,
                              (None, Material(e_b, nu_b), Material(e_j, nu_j)), is_leaf=lambda x: x is None)
        values.append(float(derived.stiffness_value(r_b, r_j)))
    values = [v for v in values if math.isfinite(v) and v > 0]
    if not values:
        return None
    unit = "Pa" if modulus else f"N/m^{HERTZ_EXPONENT:g}"
    what = (f"clearance joint {k} ({law.name} law, bearing radius {1e3 * float(r_b):.4g} mm, journal radius "
            f"{1e3 * float(r_j):.4g} mm, Young's moduli {YOUNG_MIN / 1e9:g} to {YOUNG_MAX / 1e9:g} GPa, Poisson "
            f"ratios {POISSON_MIN:g} to {POISSON_MAX:g})")
    return min(values), max(values), unit, what


def fallback_mechanism(settings: dict, fixed: dict) -> Mechanism | None:
    """The fitted mechanism rebuilt from what a :class:`~jaxclear.fitting.FitResult` reports,
    for a result made without its mechanism: the preset named ``settings["mechanism"]`` with
    the contact law ``settings["law"]`` and the known clearance ``fixed["clearance"]`` [m]
    (its default bearing radius: a preset built with another ``bearing_radius`` is not
    recognised). None when the name is no preset's."""
    from ..mechanisms.presets import PRESETS, preset

    name, law = settings.get("mechanism"), settings.get("law")
    if name not in PRESETS:
        return None
    try:
        mech = preset(name, **({"law": law} if law else {}))
        if "clearance" in fixed:
            mech = params.replace(mech, "clearance", float(fixed["clearance"]))
    except (JaxclearError, TypeError, ValueError):
        return None
    return mech


# ---- the rules -------------------------------------------------------------------------------


def _with_estimates(mech: Mechanism | None, free: Sequence[str], estimates: dict) -> Mechanism | None:
    """``mech`` with the estimates of its free geometry (clearance, exponent) put in (the
    stiffness range depends on them); the mechanism unchanged where one cannot be set."""
    if mech is None:
        return None
    for name in free:
        if name in SENSOR_PARAMETERS or params.split_name(name, mech)[0] not in ("clearance", "exponent"):
            continue
        value = estimates.get(name, math.nan)
        try:
            params.validate(mech, name, value)  # a clearance not below the bearing radius is kept out
            mech = params.replace(mech, name, value)
        except JaxclearError:
            pass
    return mech


def _unit(name: str, mech: Mechanism | None) -> str:
    """`` [unit]`` of a parameter for the messages ('' for a dimensionless one)."""
    if name in SENSOR_PARAMETERS:
        unit = SENSOR_PARAMETERS[name][0]
    else:
        unit = params.info(name, mech).unit
        if unit == "law unit":
            found = stiffness_range(mech, name) if mech is not None else None
            unit = found[2] if found else ""
    return f" {unit}" if unit and unit != "-" else ""


def _parameter_failures(name: str, value: float, sd: float, start: float | None, mech: Mechanism | None) -> list:
    """The failures of one free parameter (estimate ``value``, std ``sd``)."""
    unit, kind = _unit(name, mech), transform(name, mech)
    shown = f"{name} = {value:.6g}{unit}"
    if not math.isfinite(value):
        return [f"{shown} is not finite: the fit diverged; try other start values (--start), more starts "
                "(--starts N) or a shorter window (--window)"]
    out = []
    if kind == "logit" and min(value, 1.0 - value) < LOGIT_EDGE_DISTANCE:
        edge = 0 if value < 0.5 else 1
        out.append(f"{shown} is within {LOGIT_EDGE_DISTANCE:g} of its bound {edge} (the edge of its logit "
                   "transform): the fit ran to the edge of the range instead of an interior optimum; try more starts "
                   "(--starts 8) or other start values, a shorter window (--window), and check the contact law and the "
                   "known parameters (clearance, masses, speed)")
    if name == "sensor_gain" and not GAIN_MIN <= value <= GAIN_MAX:
        out.append(f"{shown} is outside [{GAIN_MIN:g}, {GAIN_MAX:g}]: the model cannot reproduce the scale of the "
                   "signal and the gain absorbed it; check the record's units (m/s^2, not g or mm/s^2) and the sensor "
                   "model (--sensor-cutoff-hz), and fix the gain (leave sensor_gain out of --free) unless the "
                   "accelerometer's calibration is in doubt")
    bounded = _range_failure(name, value, shown, mech)
    out += [bounded] if bounded else []
    physical = _stiffness_failure(name, value, shown, mech)
    if physical is not None:
        out += [physical] if physical else []
    elif not bounded and kind == "log" and name != "sensor_gain" and start is not None and start > 0 and value > 0:
        ratio = value / start
        if not 1.0 / LOG_RUN_FACTOR <= ratio <= LOG_RUN_FACTOR:
            toward = "infinity" if ratio > 1 else "0"
            out.append(f"{shown} is a factor {max(ratio, 1 / ratio):.3g} from its start {start:.6g}{unit} (more "
                       f"than {LOG_RUN_FACTOR:g}): the fit ran down its log transform towards {toward} instead of to "
                       "an optimum; try a start closer to the expected value, more starts (--starts N), a shorter "
                       "window (--window), and check the units of the start and of the record")
    positive = kind in ("log", "logit")
    if not math.isfinite(sd):
        out.append(f"{shown} has a standard deviation that is not finite (J^T J singular at the optimum): the record "
                   "does not determine it; free fewer parameters (fix the known ones), or fit a longer window or more "
                   "windows (--windows N) holding more impacts")
    elif positive and sd > STD_RATIO * abs(value):
        out.append(f"{shown} has a standard deviation {sd:.3g}{unit}, {sd / abs(value):.3g} times the estimate (more "
                   f"than {STD_RATIO:g}): the record does not determine it; free fewer parameters (fix the known "
                   "ones), or fit a longer window or more windows (--windows N) holding more impacts")
    return out


def _range_failure(name: str, value: float, shown: str, mech: Mechanism | None) -> str:
    """A mechanism parameter outside its range in :mod:`jaxclear.params` (for ``clearance``,
    with the mechanism, also not below the bearing radius); '' inside."""
    if name in SENSOR_PARAMETERS:
        return ""
    p = params.info(name, mech)
    below = p.low is not None and (value < p.low or (p.low_open and value == p.low))
    above = p.high is not None and (value > p.high or (p.high_open and value == p.high))
    if below or above:
        interval = (f"{'(' if p.low_open or p.low is None else '['}{'-inf' if p.low is None else f'{p.low:g}'}, "
                    f"{'inf' if p.high is None else f'{p.high:g}'}{')' if p.high_open or p.high is None else ']'}")
        return (f"{shown} is outside its range {interval} (jaxclear.params): the fit ran into the bound of its "
                "transform; try other start values (--start), more starts (--starts N) or a shorter window (--window), "
                "and check the units of the start")
    if mech is not None and params.split_name(name, mech)[0] == "clearance":
        try:
            params.validate(mech, name, value)
        except JaxclearError as err:
            return (f"{shown} is outside its range ({err}): the journal does not fit the bearing; try other start "
                    "values (--start) or more starts (--starts N), and check the units (m) of the start")
    return ""


def _stiffness_failure(name: str, value: float, shown: str, mech: Mechanism | None) -> str | None:
    """For a contact stiffness with a physical range (:func:`stiffness_range`): the failure when
    outside it, '' inside; None where no range applies."""
    if mech is None or name in SENSOR_PARAMETERS or params.split_name(name, mech)[0] != "stiffness":
        return None
    try:
        found = stiffness_range(mech, name)
    except (JaxclearError, TypeError, ValueError):
        return None
    if found is None:
        return None
    low, high, unit, what = found
    if low <= value <= high:
        return ""
    return (f"{shown} is outside the physical range {low:.3g} to {high:.3g} {unit} of {what}: no pair of materials "
            "makes this contact; try more starts (--starts N), a shorter window (--window), freeing the window start "
            "states (--windows N) or the sensor gain (--free ...,sensor_gain), and check the units of the start and "
            "of the record (SI: m/s^2, N/m^1.5)")


def _z(name: str, value: float, scale: float, mech: Mechanism | None = None) -> float:
    """The fit's transformed coordinate of a value (:func:`~jaxclear.fitting.parameters.to_z`;
    NaN outside the transform's domain)."""
    try:
        return float(to_z(name, value, scale, mech))
    except (JaxclearError, TypeError, ValueError):
        return math.nan


def _start_results(history: Iterable[dict]) -> dict:
    """Start index (1-based) -> its last record (``loss``, ``values``) among the history."""
    last = {}
    for record in history:
        m = _START_STAGE.match(str(record.get("stage", "")))
        if m and math.isfinite(float(record.get("loss", math.nan))):
            last[int(m.group(1))] = record
    return last


def _start_failures(free: Sequence[str], std: dict, history: Iterable[dict], scale: float,
                    mech: Mechanism | None = None) -> list:
    """"Estimates change with the start": per parameter, the largest disagreement between the
    best start and another start whose first-stage loss is within :data:`START_LOSS_TOLERANCE`
    of it, beyond :data:`START_STD_SPREAD` std and :data:`START_MIN_SPREAD` in ``z``."""
    starts = _start_results(history)
    if len(starts) < 2:
        return []
    best = min(starts, key=lambda j: starts[j]["loss"])
    best_loss = float(starts[best]["loss"])
    rivals = [j for j in sorted(starts) if j != best and starts[j]["loss"] <= best_loss * (1.0 + START_LOSS_TOLERANCE)]
    out = []
    for name in free:
        sd = std.get(name, math.nan)
        if not (math.isfinite(sd) and name in starts[best]["values"]):
            continue
        v_best = float(starts[best]["values"][name])
        worst = None
        for j in rivals:
            v = float(starts[j]["values"].get(name, math.nan))
            spread = abs(v - v_best)
            z_spread = abs(_z(name, v, scale, mech) - _z(name, v_best, scale, mech))
            relative = transform(name, mech) == "none"  # z in SI units (m, rad, N): compare relatively
            enough = (spread > START_MIN_SPREAD * max(abs(v), abs(v_best))) if relative else z_spread > START_MIN_SPREAD
            if spread > START_STD_SPREAD * sd and enough and (worst is None or spread > worst[1]):
                worst = (j, spread, v)
        if worst is not None:
            j, spread, v = worst
            n_std = f"{spread / sd:.3g}" if sd > 0 else "infinitely many"
            out.append(f"estimates change with the start: {name} = {v_best:.6g} from start {best} and {v:.6g} from "
                       f"start {j}, whose first-stage losses {best_loss:.4g} and {float(starts[j]['loss']):.4g} are "
                       f"within {100 * START_LOSS_TOLERANCE:g} % of each other ({n_std} std apart, more than "
                       f"{START_STD_SPREAD:g}): the record does not single out one optimum; try more starts "
                       "(--starts N), a shorter window (--window) or freeing the window start states (--windows N)")
    return out
