"""``jaxclear fit``: fit contact parameters of a preset to a measured record (JSON, PNG)."""

from __future__ import annotations

import argparse
import math
import os
import warnings

from .._errors import ParameterError
from .._extras import require_extra
from ..fitting import fit, read_channels_toml
from ..fitting.driver import AUTO_STARTS, COMPILING
from ..fitting.problem import (FIT_OUTPUT, FREE_START_ATOL, FREE_START_MAX_STEPS, FREE_START_RTOL, MAX_STEPS,
                               default_fit_settings)
from ..analysis.sensor import Accelerometer
from ..integrate import on_trace
from .common import add_mechanism_options, load_mechanism_file, name_value, number_in, preset_from_args
from .settings import add_settings_options, number_text, settings_from_args

HELP = "fit contact parameters to a measured record (JSON, PNG)"
DESCRIPTION = """\
Fit contact parameters of a preset to measured channels: by default the slider acceleration (a
CSV with the columns time_s, slider_acc_m_s2 and optionally crank_angle_rad, slider_pos_m,
slider_vel_m_s; see jaxclear.io.read_measurements); with --channel COLUMN=CHANNEL (or
--channels FILE.toml) any record columns compared with named output channels (see
jaxclear.fitting.targets), several at once with --weight COLUMN=W. Writes:
  fit.json              estimates, std (Gauss-Newton), loss, iterations, wall time, diagnostics
  fit.png               measured vs fitted acceleration and the residuals
  fit_checkpoint.json   the fit's state after every iteration: the same command resumes it
A fit whose estimates are not a result (a stiffness outside the physical range of the joint's
materials, a restitution at 0 or 1, a sensor gain outside [0.5, 2], a std larger than the
estimate, starts that disagree; see jaxclear.fitting.verdict) is reported as FAILED with its
reasons first, and fit.json says "ok": false with the "failures". Exit status: 0 (also for a
failed fit, unless --strict), 3 with --strict when the fit failed (after writing fit.json and
printing the reasons), 2 for bad input, 130 on Ctrl-C.
With --posterior also the Bayesian posterior of the free parameters and the noise level (random-walk
or NUTS chains started from the fit's optimum; see jaxclear.fitting.posterior):
  posterior.nc, posterior.json, posterior_summary.csv, posterior_pair.png,
  posterior_predictive.png/.csv, posterior_checkpoint.npz (the same command resumes it)
By default the first sample is the preset's start (crank angle 0, journal centred, velocities
from the ideal kinematics), and the loss is on short windows from that state (see
jaxclear.fitting). A laboratory record begins mid-run: give --start-state free (every
window's start state unknown, in contact or not, found by scoring candidate starts and then
fitted) with the encoder's crank angle at the first sample (--start-angle-deg, or free angle0
and speed), the sensor's filter (--sensor-cutoff-hz, --sensor-order) and, to fit them, free
sensor_gain, sensor_bias, sensor_delay.
Example: jaxclear fit data.csv --free stiffness,restitution --start stiffness=2e11 \\
         --start restitution=0.6 --sensor-cutoff-hz 20000 --out fit-out
         jaxclear fit rec.csv --preset four-bar --channel rocker_acc=body:rocker:phi:acc --window 0.005
         jaxclear fit rec.csv --mechanism my-linkage.toml --channel rocker_acc=body:rocker:phi:acc
         jaxclear fit data.csv --posterior --chains 4 --draws 500 --prior stiffness=lognormal:1e10:10
         jaxclear fit lab.csv --start-state free --start-angle-deg 37 --windows 4 --window 0.00299 \
         --free stiffness,restitution,sensor_gain,sensor_bias --sensor-cutoff-hz 10000 --strict"""


def configure(p: argparse.ArgumentParser):
    """Add the options of ``jaxclear fit``; returns its ``run(args) -> exit code``."""
    p.add_argument("data", metavar="DATA.csv", help="measured record (time_s, slider_acc_m_s2, ...)")
    add_mechanism_options(p, "model (known values; free parameters start from them unless --start)", ideal=False,
                          needs_slider=True)
    p.add_argument("--mechanism", metavar="FILE.toml",
                   help="mechanism file (TOML, docs/mechanism-files.md) to fit instead of --preset; its physical "
                   "options (--clearance, --restitution, ...) apply to every clearance joint (default: use --preset)")
    f = p.add_argument_group("fit")
    f.add_argument("--free", default="stiffness,restitution", metavar="NAMES",
                   help="comma-separated free parameters: stiffness [N/m^1.5 for the LN family], restitution, "
                   "friction, clearance [m], mass:BODY, angle0 [rad], speed [rad/s], ..., sensor_gain, sensor_bias, "
                   "sensor_delay [s] (default: stiffness,restitution)")
    f.add_argument("--start", type=name_value, action="append", default=[], metavar="NAME=VALUE",
                   help="start value of a free parameter (SI), repeatable (default: the model's value)")
    f.add_argument("--channel", type=column_channel, action="append", default=[], metavar="COLUMN=CHANNEL",
                   help="fit the record column COLUMN to the named output channel CHANNEL (e.g. "
                   "rocker_acc=body:rocker:phi:acc), repeatable (default: slider_acc_m_s2=body:SLIDER:x:acc)")
    f.add_argument("--weight", type=name_value, action="append", default=[], metavar="COLUMN=W",
                   help="weight of a --channel column's normalised squared residual, not negative, repeatable "
                   "(default: 1)")
    f.add_argument("--channels", metavar="FILE.toml",
                   help="a [channels] table: COLUMN = \"CHANNEL\" or COLUMN = {channel, weight, cutoff_hz, gain, "
                   "bias} (a sensor of its own); combined with --channel/--weight")
    f.add_argument("--window", type=number_in(float, 0.0, low_open=True), metavar="S",
                   help="length of a fit window [s], > 0, holding at least 4 samples (default: a quarter crank "
                   "revolution, shortened to the record's span over --windows when the record is shorter)")
    f.add_argument("--windows", type=number_in(int, 1), default=1, metavar="N",
                   help="back-to-back windows, >= 1; windows after the first estimate their journal state "
                   "(default: 1)")
    f.add_argument("--start-state", choices=("known", "free"), default="known",
                   help="known: the record begins at the mechanism's start (start-up); free: it begins mid-run, the "
                   "state at every window's start is unknown (in contact or not) and fitted (default: known)")
    f.add_argument("--start-angle-deg", type=number_in(float), metavar="DEG",
                   help="crank angle at the record's first sample [deg] (an encoder), sets the crank's angle0 "
                   "(default: the mechanism's, 0 for the presets); free angle0 to fit it")
    f.add_argument("--starts", type=number_in(int, 1), default=None, metavar="N",
                   help="number of starts of the first stage, >= 1 (default: 1, and the whole fit again from "
                   f"{AUTO_STARTS} starts where one start stops on --max-iter or leaves a residual that is not white)")
    f.add_argument("--profile", default=None, metavar="NAMES",
                   help="free parameters (comma-separated, or 'all') whose profile likelihood is walked after the "
                   "fit: each held at up to 20 values (6 a side, 4 more where the loss jumps) while the other unknowns are fitted again; their 90 %% "
                   "interval replaces the Gauss-Newton std (an honest one where the loss is not quadratic) and "
                   "a better fit found on the way fails the fit; with the same --out, adding it to a finished fit "
                   "runs only the profile (default: none)")
    f.add_argument("--scan", default="auto", metavar="NAME[=V1,V2,...]|auto|none",
                   help="a free parameter of the mechanism fitted again after the fit with it held at each value "
                   "(default: two, either side of the estimate), the window starts searched anew at each; where "
                   "one fits better than the estimate, every unknown is fitted again from it and that result is "
                   "taken; its profile likelihood is then walked. For records that begin mid-run "
                   "(--start-state free) whose estimate of a weakly determined parameter must be trusted; costs "
                   "one whole fit per value, each checkpointed in OUT/scan-NAME-VALUE. 'auto' (default): the "
                   "restitution where every window's start is free (--start-state free) and the fitted motion "
                   "holds fewer than 4 contact onsets, nothing elsewhere; 'none': no scan")
    f.add_argument("--optimizer", default="levenberg-marquardt", metavar="NAME",
                   help="levenberg-marquardt (optimistix's LevenbergMarquardt on the residual vector) or "
                   "adam[:LR] (optax's adam on the loss's gradient, learning rate LR in the transformed "
                   "parameters, 0.02 if omitted) (default: levenberg-marquardt)")
    f.add_argument("--max-iter", type=number_in(int, 1), default=30, metavar="N",
                   help="iterations of the last stage, >= 1; earlier stages get half (default: 30)")
    f.add_argument("--align", choices=("time", "crank"), default="time",
                   help="first sample = simulation start ('time') or simulation time from crank_angle_rad "
                   "('crank') (default: time)")
    f.add_argument("--time-offset", type=number_in(float), default=0.0, metavar="S",
                   help="added to the record's times with --align time [s]; a delay to fit is sensor_delay "
                   "(default: 0)")
    # the model's integration: the fit's own settings where an option is not given (jaxclear.fit's settings)
    fit_defaults = default_fit_settings()
    add_settings_options(p, fit_defaults, title="integration of the model", shown={
        "--rtol": f"{number_text(fit_defaults.rtol)}, {number_text(FREE_START_RTOL)} with --start-state free",
        "--atol": f"{number_text(fit_defaults.atol)}, {number_text(FREE_START_ATOL)} with --start-state free",
        "--max-steps": f"{MAX_STEPS}, {FREE_START_MAX_STEPS} with --start-state free",
        "--derivative-tolerance": "1 where rtol <= 1e-7, else 0.1; 0.1 given counts as not given",
        "--output-sampling": f"{FIT_OUTPUT.name}; loop given counts as not given"})
    s = p.add_argument_group("sensor model")
    s.add_argument("--sensor-cutoff-hz", type=number_in(float, 0.0, low_open=True), metavar="HZ",
                   help="accelerometer low-pass cut-off [Hz], > 0 (default: none)")
    s.add_argument("--sensor-order", type=int, choices=(1, 2), default=2,
                   help="order of the low-pass: 1 (first-order) or 2 (Butterworth) (default: 2)")
    s.add_argument("--sensor-delay", type=number_in(float), default=0.0, metavar="S",
                   help="delay of the record behind the model [s]; free sensor_delay to fit it (default: 0)")
    s.add_argument("--sensor-gain", type=number_in(float), default=1.0, metavar="G", help="accelerometer gain [-] (default: 1)")
    s.add_argument("--sensor-bias", type=number_in(float), default=0.0, metavar="B",
                   help="accelerometer bias [m/s^2] (default: 0)")
    s.add_argument("--oversample", type=number_in(int, 1), default=4, metavar="N",
                   help="model grid points per record sample, >= 1 (default: 4)")
    b = p.add_argument_group("posterior (Bayesian identification)")
    b.add_argument("--posterior", action="store_true",
                   help="after the fit, sample the posterior of the free parameters and the noise level (windows = 1 "
                   "only) (default: off)")
    b.add_argument("--sampler", choices=("random-walk", "nuts"), default="random-walk",
                   help="random-walk Metropolis (one simulation a draw, indifferent to the jumps of the likelihood at "
                   "the default window) or NUTS (gradients; for many free parameters and a smooth likelihood) "
                   "(default: random-walk)")
    b.add_argument("--chains", type=number_in(int, 1), default=4, metavar="N", help="chains, >= 1 (default: 4)")
    b.add_argument("--draws", type=number_in(int, 1), metavar="N",
                   help="kept draws per chain, >= 1, rounded up to a multiple of --chunk (default: 2000 random-walk, "
                   "500 NUTS)")
    b.add_argument("--warmup", type=number_in(int, 0), metavar="N",
                   help="warm-up draws per chain (step tuning, discarded), >= 0, rounded up to a multiple of --chunk "
                   "(default: 500 random-walk, 200 NUTS)")
    b.add_argument("--chunk", type=number_in(int, 1), metavar="N",
                   help="draws per checkpointed chunk, >= 1 (default: 250 random-walk, 50 NUTS)")
    b.add_argument("--prior", type=name_prior, action="append", default=[], metavar="NAME=KIND:A[:B]",
                   help="prior of a free parameter or of noise_sigma: normal:MEAN:SD, lognormal:MEDIAN:FACTOR, "
                   "uniform:LOW:HIGH, halfnormal:SCALE, repeatable (default: lognormal with a factor 10 around the "
                   "start for positive parameters, uniform(0, 1) for restitution, halfnormal(data RMS) for the noise)")
    b.add_argument("--noise-sigma", type=number_in(float, 0.0, low_open=True), metavar="S",
                   help="the sensor's noise standard deviation [unit of the first column], > 0, measured on a record "
                   "of the machine at rest: the fit's verdict tests the residual against it and the posterior holds "
                   "the noise level at it (default: unknown; the posterior samples it)")
    b.add_argument("--seed", type=number_in(int, 0), default=0, metavar="N", help="random seed, >= 0 (default: 0)")
    out = p.add_argument_group("output")
    out.add_argument("--out", default="./jaxclear-fit", metavar="DIR",
                     help="output folder, created if missing (default: ./jaxclear-fit)")
    out.add_argument("--restart", action="store_true", help="ignore a checkpoint in --out instead of resuming")
    out.add_argument("--no-plots", action="store_true", help="write fit.json only (default: off)")
    out.add_argument("--no-progress", action="store_true", help="hide the progress bar (default: shown)")
    out.add_argument("--strict", action="store_true",
                     help="exit with status 3 when the fit failed its checks (fit.json written first, with \"ok\": "
                     "false and the reasons; --posterior is then skipped); without it a failed fit prints FAILED "
                     "and its reasons and exits with 0 (default: off)")
    return run


def _scan(text: str | None):
    """``--scan``: None ('none'), 'auto', a name, or ``{name: [values]}`` from ``NAME=V1,V2,...``
    (checked by the fit)."""
    if text is not None and text.strip().lower() == "none":
        return None
    if text is None or "=" not in text:
        return text.strip() if text else None
    name, _, values = text.partition("=")
    try:
        return {name.strip(): [float(v) for v in values.split(",") if v.strip()]}
    except ValueError:
        raise ParameterError(f"--scan {text!r}: expected NAME or NAME=V1,V2,... with numbers") from None


def _profile_names(text: str | None):
    """``--profile``: None, True for 'all', or the names."""
    if text is None:
        return None
    if text.strip() == "all":
        return True
    return [n.strip() for n in text.split(",") if n.strip()]


def run(args) -> int:
    """Check the counts, fit, write fit.json and fit.png, print the estimates."""
    mech = load_mechanism_file(args, args.mechanism) if args.mechanism else preset_from_args(args)
    channels = _channels(args)
    scan = _scan(args.scan)
    free = [n.strip() for n in args.free.split(",") if n.strip()]
    sensor = Accelerometer(args.sensor_cutoff_hz, gain=args.sensor_gain, bias=args.sensor_bias,
                           oversample=args.oversample, order=args.sensor_order, delay=args.sensor_delay)
    if args.start_angle_deg is not None:
        from .. import params

        mech = params.replace(mech, "angle0", math.radians(args.start_angle_deg))
    if args.posterior:  # its inputs and packages checked before the fit
        from ..fitting.posterior import check_priors

        require_extra("uncertainty", "jaxclear fit --posterior")

        if args.windows != 1:
            raise ParameterError(f"--posterior models window 0 only (it starts from the known state): use --windows 1, "
                                 f"not {args.windows}")
        check_priors(tuple(free), dict(args.prior))
    os.makedirs(args.out, exist_ok=True)
    laws = "the file's contact laws" if args.mechanism else args.model
    print(f"jaxclear fit: {args.data}, {mech.name} with {laws}, free {', '.join(free)}; sensor: "
          f"{sensor.describe()}", flush=True)
    told = []

    def compiling(name: str):  # with the bar, fit() itself says so
        if args.no_progress and not told:
            told.append(name)
            print(f"{COMPILING}...", flush=True)

    with warnings.catch_warnings(), on_trace(compiling):  # the fit's warnings are printed below, once
        warnings.simplefilter("ignore", UserWarning)
        res = fit(args.data, mech, free, dict(args.start), channels=channels, sensor=sensor, window=args.window, windows=args.windows,
                  start_state=args.start_state, starts=args.starts, optimizer=args.optimizer, max_iter=args.max_iter,
                  settings=_settings(args), align=args.align, time_offset=args.time_offset, out=args.out, resume=not args.restart,
                  progress=not args.no_progress, profile=_profile_names(args.profile), noise_sigma=args.noise_sigma,
                  scan=scan)
    files = res.write(args.out, plots=not args.no_plots)
    _print_result(res, files)
    if not res.ok and args.strict:
        print(f"error: the fit failed {len(res.failures)} check(s) (--strict): exit status 3"
              + ("; the posterior is skipped" if args.posterior else ""), flush=True)
        return 3
    if args.posterior:
        _posterior(args, mech, free, channels, sensor, res)
    return 0


def name_prior(text: str) -> tuple[str, str]:
    """argparse type: ``NAME=KIND:A[:B]`` (checked by the posterior, which names the parameter)."""
    name, sep, spec = text.partition("=")
    if not sep or not name.strip() or not spec.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=KIND:A[:B] (e.g. stiffness=lognormal:1e10:10), got {text!r}")
    return name.strip(), spec.strip()


def _settings(args):
    """The model's settings from the integration options given over the fit's own
    (:func:`~jaxclear.fitting.problem.default_fit_settings`, those of free starts with
    ``--start-state free``); None where none is given (the fit's own, whole)."""
    return settings_from_args(args, default_fit_settings(args.start_state == "free"), none_if_unset=True)


def _posterior(args, mech, free, channels, sensor, res):
    """``--posterior``: sample, write the files, print the summary (flagged when not converged)."""
    from ..fitting import posterior
    from ..fitting.posterior import DEFAULT_COUNTS

    n = {k: DEFAULT_COUNTS[args.sampler][k] if getattr(args, k) is None else getattr(args, k) for k in ("draws", "warmup")}
    print(f"jaxclear fit: posterior, {args.chains} chain(s) x ({n['warmup']} warm-up + {n['draws']} draws), "
          f"{'NUTS' if args.sampler == 'nuts' else 'random-walk Metropolis'} from the least-squares optimum", flush=True)
    with warnings.catch_warnings():  # the diagnostics' warnings are printed by the summary
        warnings.simplefilter("ignore", UserWarning)
        post = posterior(args.data, mech, free, dict(args.start), fit_result=res, priors=dict(args.prior),
                         noise_sigma=args.noise_sigma, chains=args.chains, draws=args.draws, warmup=args.warmup,
                         chunk=args.chunk, sampler=args.sampler, seed=args.seed, channels=channels, sensor=sensor, windows=args.windows,
                         settings=_settings(args), align=args.align, out=args.out, resume=not args.restart,
                         progress=not args.no_progress)
    print(f"posterior in {post.wall_time_s:.1f} s wall ({post.gradient_evaluations} gradient evaluations); "
          + post.summary())
    print(f"wrote {os.path.join(args.out, 'posterior.nc')} and posterior.json, posterior_summary.csv, "
          "posterior_pair.png, posterior_predictive.png/.csv")


def column_channel(text: str) -> tuple[str, str]:
    """argparse type: ``COLUMN=CHANNEL`` (the channel name may hold ``=`` in its options)."""
    column, sep, name = text.partition("=")
    if not sep or not column.strip() or not name.strip():
        raise argparse.ArgumentTypeError(f"expected COLUMN=CHANNEL, got {text!r}")
    return column.strip(), name.strip()


def _channels(args) -> dict | None:
    """column -> spec from --channels, --channel and --weight (None: the default target)."""
    table = dict(read_channels_toml(args.channels)) if args.channels else {}
    for column, name in args.channel:
        table[column] = name
    for column, weight in args.weight:
        if column not in table:
            raise ParameterError(f"--weight {column}={weight:g}: {column!r} is not a fitted column "
                                 f"(give it with --channel {column}=CHANNEL); fitted: {sorted(table)}")
        spec = table[column]
        table[column] = dict(spec, weight=weight) if isinstance(spec, dict) else {"channel": spec, "weight": weight}
    return table or None


def _print_result(res, files: list[str]):
    """Print the fit's outcome (a failed fit: FAILED and its reasons first, and once more at the
    end), the estimates with their start values and std, and warnings."""
    if not res.ok:
        print(res.format_failures())
    width = max(len(n) for n in res.estimates)
    resumed = " (resumed from the checkpoint)" if res.settings.get("resumed") else ""
    print(f"done in {res.wall_time_s:.1f} s wall{resumed}, {res.iterations} iterations ({res.stop_reason}); "
          f"loss {res.loss:.4g}, residual lag-1 autocorrelation {res.residual_autocorrelation:.2f}")
    print(f"  {'parameter':<{width}}  {'start':>12}  {'estimate':>12}  {'std':>10}")
    for name, value in res.estimates.items():
        print(f"  {name:<{width}}  {res.start[name]:>12.6g}  {value:>12.6g}  {res.std[name]:>10.3g}")
    for line in res.profile_lines():
        print(line)
    for note in res.settings.get("skipped_stages", []):
        print(f"note: stage {note}")
    if res.settings.get("auto_starts"):
        print(f"note: fitted from {res.settings['auto_starts']}")
    for w in res.warnings:
        print(f"warning: {w}")
    print("wrote " + ", ".join(files))
    if not res.ok:
        print(f"FAILED: {len(res.failures)} reason(s) above; the estimates are not a result", flush=True)
