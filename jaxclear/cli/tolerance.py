"""``jaxclear tolerance``: a tolerance study from a TOML file (JSON, CSV, PNG)."""

from __future__ import annotations

import argparse
import os
import warnings

from .._xla_flags import request_host_devices
from ..tolerance.config import load_study
from ..tolerance.estimators import UnresolvedEstimateWarning
from ..tolerance.study import tolerance_study
from .settings import add_settings_options, given_options
from .sweep import sweep_settings

HELP = "tolerance study: distributions of parameters -> distributions of metrics, exceedance, sensitivity"
DESCRIPTION = """\
Sample the distributions of named parameters (normal, uniform, truncated normal; optional
correlations) given in a TOML file, run the mechanism for every sample on the sweep's machinery
(every device, chunk by chunk, resumed by the same command), and report the metrics'
distributions, the probability that a metric exceeds its limit (95 % interval) beside the
linearised estimate (flagged where it leaves the metric's range), Sobol' first and total
indices with their 95 % intervals, flagged where the runs do not resolve them ([study] sobol_n)
and importance sampling
for small probabilities ([study] importance_n). File format: python -c "import
jaxclear.tolerance.config as c; print(c.__doc__)". Writes into the output folder:
  tolerance.json       summary, exceedance, linearised, Sobol' indices, importance sampling
  tolerance_runs.csv   the sampled parameters and the metrics of every run
  tolerance.png        histograms of the metrics with the limits and the linearised density
  runs/ linearised/ sobol/ importance/   one sweep folder per batch of runs (resumable)
Example: jaxclear tolerance examples/tolerance.toml --out tol-out"""


def configure(p: argparse.ArgumentParser):
    p.add_argument("study", metavar="STUDY.toml", help="tolerance study file (TOML)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: the file's output.dir, else ./tolerance-out)")
    p.add_argument("--restart", action="store_true", help="discard results already in the folder instead of resuming")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bars (default: shown)")
    add_settings_options(p, sweep_settings(), title="integration (each option given replaces the file's [settings] "
                         "value; defaults: a sweep's without one)")
    return run


def run(args) -> int:
    """Load the study (every key checked), run it, print the summary."""
    request_host_devices()
    kwargs = load_study(args.study, settings_options=given_options(args))
    if args.out:
        kwargs["out"] = args.out
    if args.no_progress:
        kwargs["progress"] = False
    with warnings.catch_warnings():  # printed in the summary below, once
        warnings.simplefilter("ignore", UnresolvedEstimateWarning)
        res = tolerance_study(**kwargs, restart=args.restart)
    print(f"jaxclear tolerance: {res.summary()}")
    print(f"wrote {os.path.join(kwargs['out'], 'tolerance.json')}, tolerance_runs.csv, tolerance.png")
    return 0
