r"""Identification of contact parameters from a measured slider acceleration, or from any
record columns mapped to named output channels (:mod:`.targets`):
``jaxclear.fit(data, mech, ...)`` (:func:`fit`) and ``jaxclear fit DATA.csv``.

Below, "the slider acceleration" stands for the fitted columns: with ``channels`` every column
is compared with its channel through its own sensor model and weight, and the residuals of all
columns are stacked (:mod:`.window`); the windows, continuations, optimiser and uncertainty are
the same.

The problem
-----------
A record (:class:`jaxclear.io.Measurements`: time [s], slider acceleration [m/s^2], optionally
the crank angle [rad]) holds the slider acceleration of a mechanism whose clearance joint
rattles. The model is :func:`jaxclear.simulate` of a preset with some parameters free
(default ``stiffness`` and ``restitution``), seen through the accelerometer model of
:mod:`jaxclear.sensor` (low-pass, gain, bias). The record is *chaotic*: at 5000 rpm two
trajectories of the Flores benchmark that differ by 1e-9 in restitution separate visibly after
a few milliseconds, so a least-squares loss on a long record is a landscape of narrow local
minima in which no optimiser finds the truth, and its gradient is dominated by the timing of
late impacts that no parameter controls smoothly.

The loss (the choice, and why)
------------------------------
What *is* deterministic is the start: the preset starts from a known state (crank angle 0,
journal centred, velocities from the ideal kinematics) at the first sample, and the first
impacts follow from it and from the parameters alone. So the loss is a least-squares misfit of
the sensor signal on **short windows**:

* **window 0** starts from that known state and has no extra unknowns. Its length is
  ``window`` seconds (default a quarter of a crank revolution: 3 ms and about 7 impacts at
  5000 rpm, 75 ms and about 9 impacts at 200 rpm).
* **windows 1..W-1** (``windows=W``, optional) follow it back to back; each starts from a
  journal state that is *not* known: the journal's offset in the bearing (2) and its velocity
  relative to the bearing (4 numbers per clearance joint) are extra unknowns of the fit
  (multiple shooting without continuity constraints: every window re-anchors the chaotic
  trajectory on the data). The rest of the start state follows from the constraints and the
  driver. Window ``k`` is simulated from ``t = 0`` with the crank's start angle advanced by
  ``omega k T_w`` (so the mechanism's only time dependence must be its :class:`AngleDriver`),
  and the first ``2 / f_c`` seconds of its samples are left out, because the sensor filter's
  history before the window is unknown.
* **continuation in the horizon**: a 3x error in stiffness moves the later impacts of even a
  3 ms window by more than their width, and the loss of the whole window is then non-convex.
  So every window is first fitted on the first quarter of its samples, then the first half,
  then all of them (``horizons``), each stage starting from the previous estimate; a partial
  horizon ends at the quietest record sample within the next 10 % of the window, so that it
  does not cut an impact in half. On the benchmark record the loss restricted to the first
  0.75 ms is unimodal over stiffness [1/3, 3] x true and restitution [0.5, 0.99]. A stage whose
  unknowns change none of its samples (a horizon that ends before the first contact: its
  Jacobian is exactly zero) is skipped and listed in ``settings["skipped_stages"]``; a final
  stage without influence is a :class:`~jaxclear.FitDataError`
  (:func:`jaxclear.fitting.run.run_stage`).
* **continuation in the signal** (``coarse="velocity"``, default): impacts are spikes a few
  samples wide; when the model's spike sits beside the measured one, the squared difference
  does not tell which way to move (at 200 rpm the restitution landscape of the acceleration
  loss has a local minimum 0.1 from the truth even over two impacts). The integral of the
  acceleration (the slider's velocity change) turns each spike into a step, whose misfit
  grows smoothly with the timing error. So the first stage of every window fits the running
  integral of the residual, and the later stages the acceleration itself (which carries the
  stiffness, through the spike shapes). Without this stage the Flores 2011 rig fit from 3x
  stiffness and restitution 0.6 ends at (0.6 x stiffness, 0.32); with it at the truth.
* The residual is ``(model - measured) / rms(measured)`` at the record's samples, so the
  reported ``loss`` (its mean square over the fitted samples) is the normalised misfit: about
  ``10**(-SNR/10)`` (0.01 at 20 dB) for an exact model, larger with a model error.

A record that begins mid-run (``start_state="free"``; a laboratory record: crank turning for
minutes, the journal pressed into its bearing, the contact under way begun before the first
sample) has no known start: every window's start state, the first included, is an unknown in
the "anywhere" layout of :mod:`.window_start` (in contact too, with the ongoing contact's
approach speed), first **found** by scoring candidate starts on the window's first part
(:mod:`.way_in`) and then fitted, window by window at the start values and then jointly with the
parameters (:func:`.plan.plan_free_starts`). The crank's angle at the first sample is the
mechanism's ``angle0`` (an encoder), or fitted (``angle0``, ``speed`` free); a clock offset is
``sensor_delay``.

Per-revolution statistics (quantiles of the acceleration, band powers of its spectrum) are not
the default: where the trajectory can be followed it holds far more (on the laboratory records
the statistics fit determines the stiffness to 15-25 % through a 10 kHz sensor, one std, while a
followed trajectory determines it to a few per cent). Where a record is longer than the motion's
predictability and the trajectory cannot be followed, they are the method:
:func:`fit_statistics` (Wood's synthetic likelihood on a grid, with the revolutions' spread as
the statistics' covariance; theory page "Fitting the statistics of a record").

The optimiser
-------------
The fit minimises ``0.5 |r(z)|^2`` over unconstrained coordinates ``z`` (the transforms of
:mod:`jaxclear.params`: ``log`` stiffness, clearance, friction, masses; ``logit``
restitution; plus ``sensor_gain`` (log) and ``sensor_bias`` (scaled by the data RMS);
:mod:`.parameters`). The residual Jacobian ``dr/dz`` is computed in **forward mode**
(``jax.jacfwd`` of the window model, whose simulations give the error-controlled sensitivities of
:mod:`jaxclear.integrate._sensitivity`: the tangents of the free parameters and window start
states integrated with the state and in its step-size control): there are a handful of columns
and hundreds of rows.

Every stage is solved by :class:`optimistix.LevenbergMarquardt` (Gauss-Newton with damping
``(J^T J + lambda I) dx = -J^T r``, ``lambda`` updated by Nielsen's rule, accepted steps
extended along curved valleys, :mod:`.lm`; Levenberg 1944, Marquardt 1963, Nielsen 1999),
driven one ``step`` at a time so that the state can be checkpointed between steps (:mod:`.solver`). The Jacobian is handed to it materialised (one
forward-mode pass per window and step). An optax first-order optimiser may be passed instead
(``optimizer=optax.adam(0.02)`` or ``"adam:0.05"``; run by :class:`optimistix.OptaxMinimiser`
on ``0.5 |r|^2`` with the same forward-mode gradient ``J^T r``). It is not a good choice here:
on the acceptance problem adam (learning rate 0.05) had not reached the truth after 300
iterations (stiffness still 45 % off; ``benchmarks/bench_fit.py --adam``). The Gauss-Newton
matrix is what makes the fit converge, so it is the default rather than an optional polish.

Stopping: per stage, at most ``max_iter`` trial steps (intermediate horizons ``max_iter // 2``,
at least 5); a stage ends when an accepted step lowers the loss by less than ``ftol``
(relative; at least 1e-3 for intermediate horizons), when an accepted step lowers the sum of
squares by less than a tenth of a noise variance (``s^2 = SS / (N - P)``:
:data:`jaxclear.fitting.run.DEVIANCE_TOL`, the same rule in the statistics' units, where the
estimates no longer move by a meaningful part of their uncertainty), when an accepted step is
below ``xtol`` in every coordinate, when the trust region shrinks below 1e-10 (no decreasing step), or on
optimistix's Cauchy criterion (``rtol=ftol``, ``atol=xtol``). An iteration is one trial step:
one evaluation of the model and its Jacobian, accepted or rejected.

Several starts: ``starts=N`` fits the first (shortest) horizon of window 0 from ``N`` starts
(the given one and ``N - 1`` others spread deterministically by +-log 3 in the log
parameters and +-1 in logit restitution around it) and continues from the best. By default
(``starts=None``) a fit starts once and, where that start stops on ``max_iter`` or leaves a
residual that is not white (lag-1 autocorrelation above 0.3), fits again from
:data:`~jaxclear.fitting.driver.AUTO_STARTS` starts (4), whose result it returns
(``FitResult.settings["auto_starts"]`` says why); a fit that still ends so warns and names
``starts`` and ``start``. Both fits checkpoint into ``out``, the refit from the switch on with
the single start's reason: a fit killed in the single start, at the switch or in the refit
resumes where it stopped and says so (``settings["resumed"]``).

Uncertainty
-----------
At the optimum, with all windows and all samples, ``sigma^2 = |r|^2 / (N - P)`` (residual in
m/s^2, ``N`` samples, ``P`` unknowns including the window states) and
``Cov(z) = sigma^2 (J^T J)^{-1}`` (Gauss-Newton approximation of the Fisher information for
white Gaussian noise); the standard deviation of each parameter follows by the delta method,
``std(theta) = |d theta / d z| std(z)`` (:mod:`.uncertainty`). This is honest only if the
residual is white noise: ``fit.json`` reports the lag-1 autocorrelation of the residuals (about
0 for white noise; near 1 when the model cannot reproduce the data, e.g. a different contact
law), and the fit warns when it exceeds 0.3, because then the std understate the error. The
Gauss-Newton std is the curvature at the minimum; ``fit(..., profile=NAMES)`` walks the profile
likelihood instead (:mod:`.profile`: each parameter held at values round the estimate, the
other unknowns fitted again, the 90 % interval where the loss rises by less than 2.706 noise
variances), honest where the loss is not quadratic or jumps (a contact that appears).
``fit(..., scan=NAME)`` fits the record again with the parameter held either side of the
estimate, every window's start searched anew, and takes the better fit (:mod:`.scan`: the way
out of a basin that a window's start found elsewhere bends the parameter into); by default
(``scan="auto"``) the restitution where every window's start is free and the fitted motion holds
fewer than four contact onsets.

Resuming
--------
With ``out`` given, the state of the fit (:class:`FitState`: stage, iteration, unknowns, the
optimistix solver state, history) is written atomically to ``out/fit_checkpoint.json`` after
every step, keyed by a fingerprint of the data and of every setting. A fit started again with
the same inputs resumes where it stopped, from bit-identical numbers; other inputs start afresh.

Modules
-------
:mod:`.parameters` (names, values, transforms), :mod:`.records` (synthetic records, writing,
checks, quiet cut), :mod:`.targets` (record columns mapped to named channels), :mod:`.window` (the window model and the record cut into windows),
:mod:`.window_start` (a window's unknown start), :mod:`.way_in` (candidate starts scored),
:mod:`.verdict` (whether the estimates are a result),
:mod:`.plan` (stages and starts), :mod:`.profile` (the profile likelihood), :mod:`.scan` (held values, starts searched anew), :mod:`.problem` (the checked inputs), :mod:`.state` (the fit
state and its checkpoint), :mod:`.solver` (optimistix steps of one stage), :mod:`.run` (the
plan with checkpoints), :mod:`.uncertainty`, :mod:`.verdict` (:func:`assess`: whether the
estimates are a result; ``FitResult.failures``, ``FitResult.ok``), :mod:`.result` (:class:`FitResult`),
:mod:`.driver` (:func:`fit`), :mod:`.priors`, :mod:`.posterior_model`, :mod:`.sampler`,
:mod:`.posterior` (:func:`posterior`: the Bayesian posterior of the fit), :mod:`.posterior_result`,
:mod:`.gradients` (:func:`parameter_grad`), :mod:`.legacy`
(the deprecated NumPy Levenberg-Marquardt).
Statistics fit (records longer than the motion's predictability): :mod:`.statistics` (per-revolution
statistics, synthetic likelihood), :mod:`.statistics_model` (the grid's runs), :mod:`.statistics_surrogate`
(between the nodes, the noise profiled), :mod:`.statistics_result`, :mod:`.statistics_fit` (:func:`fit_statistics`).
"""


from .driver import fit
from .gradients import parameter_grad, slider_power_loss
from .legacy import LevenbergMarquardt, LMState, levenberg_marquardt
from .parameters import DEFAULT_FREE, SENSOR_PARAMETERS, from_z, to_z
from .plan import DEFAULT_HORIZONS, Stage
from .posterior import POSTERIOR_CHECKPOINT, posterior
from .posterior_result import PosteriorResult
from .priors import HalfNormal, LogNormal, Normal, Uniform
from .records import check_record, quiet_cut, sensor_signal, synthetic_record, write_measurements
from .result import FitResult
from .solver import Optimizer, make_optimizer
from .statistics_fit import fit_statistics
from .statistics_result import StatisticsFitResult
from .state import CHECKPOINT_NAME, Checkpoint, FitState
from .targets import DEFAULT_COLUMN, FitChannel, read_channels_toml
from .uncertainty import AUTOCORRELATION_WARNING
from .verdict import assess, stiffness_range
from .window import WindowInput, WindowModel, evaluate_window

__all__ = [
    "fit",
    "fit_statistics",
    "StatisticsFitResult",
    "posterior",
    "PosteriorResult",
    "POSTERIOR_CHECKPOINT",
    "Normal",
    "LogNormal",
    "Uniform",
    "HalfNormal",
    "FitChannel",
    "DEFAULT_COLUMN",
    "read_channels_toml",
    "FitResult",
    "assess",
    "stiffness_range",
    "FitState",
    "Checkpoint",
    "CHECKPOINT_NAME",
    "make_optimizer",
    "Optimizer",
    "levenberg_marquardt",
    "LevenbergMarquardt",
    "LMState",
    "synthetic_record",
    "sensor_signal",
    "write_measurements",
    "check_record",
    "quiet_cut",
    "parameter_grad",
    "slider_power_loss",
    "to_z",
    "from_z",
    "DEFAULT_FREE",
    "DEFAULT_HORIZONS",
    "SENSOR_PARAMETERS",
    "AUTOCORRELATION_WARNING",
    "Stage",
    "WindowModel",
    "WindowInput",
    "evaluate_window",
]
