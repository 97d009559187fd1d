"""Gradient and fit timings (issue 4, item 6).

1. Reverse-mode gradient time over forward-mode gradient time for a one-crank-revolution window
   of the Flores benchmark (5000 rpm: 12 ms, about 50 impacts), loss = mean(slider_acc^2) / 1e8,
   with respect to P parameters (default the 3 of the lead's measurement: stiffness, restitution,
   friction). Reverse: ``jax.grad`` through diffrax's RecursiveCheckpointAdjoint (``--checkpoints``);
   forward: ``jax.jacfwd`` with ``adjoint="forward"`` (P tangents). Steady state = median of
   ``--repeats`` calls after the first (compiling) one. Target: reverse / forward <= 4.
2. The fit's wall time on the acceptance problem: the benchmark record of 3.2 ms (200 kHz, 20 kHz
   sensor, SNR 20 dB), stiffness and restitution from 3x and 0.3 off; first fit of the process
   (with compilation) and a second fit of the same problem (compiled). ``--rig`` adds the Flores
   2011 rig (80 ms record at 50 kHz, 5 kHz sensor); ``--adam`` adds the same benchmark fit with
   optax.adam instead of Levenberg-Marquardt.

Run from the repository root: ``PYTHONPATH=. python benchmarks/bench_fit.py [--rig] [--adam]``.
Results: printed table and ``benchmarks/results/fit.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import tempfile
import time

import jaxclear as jc  # noqa: I001  (float64 first)

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxclear import params
from jaxclear.fitting import slider_power_loss
from jaxclear.analysis.sensor import Accelerometer

NAMES = ("stiffness", "restitution", "friction", "clearance", "mass:slider", "speed_rpm")
UNITS = {"stiffness": 1e10, "restitution": 1.0, "friction": 1.0, "clearance": 1e-3, "mass:slider": 1.0,
         "speed_rpm": 1000.0}


def _timed(fn, *args, repeats=3):
    t = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t)
    return out, first, statistics.median(times), times


def gradient_ratio(revolutions: float, n_params: int, checkpoints: int | None, repeats: int, rtol: float):
    mech = jc.preset("flores-slider-crank", friction=0.05)
    names = NAMES[:n_params]
    units = np.array([UNITS[n] for n in names])
    t_end = revolutions * jc.crank_period(mech)
    s = jc.settings(t_end, n_out=int(2000 * revolutions) + 1, rtol=rtol, atol=rtol * 1e-3, checkpoints=checkpoints)

    def make(settings):
        return slider_power_loss(mech, names, units, settings)

    x0 = jnp.asarray([float(params.get(mech, n)) for n in names]) / units
    primal = eqx.filter_jit(make(s))
    rev = eqx.filter_jit(jax.grad(make(s)))
    fwd = eqx.filter_jit(jax.jacfwd(make(dataclasses.replace(s, adjoint="forward"))))
    out = {}
    value, out["primal_first_s"], out["primal_s"], _ = _timed(primal, x0, repeats=repeats)
    g_rev, out["reverse_first_s"], out["reverse_s"], out["reverse_all_s"] = _timed(rev, x0, repeats=repeats)
    g_fwd, out["forward_first_s"], out["forward_s"], out["forward_all_s"] = _timed(fwd, x0, repeats=repeats)
    sol = jc.simulate(mech, s)
    out.update(
        window_s=t_end, revolutions=revolutions, parameters=list(names), checkpoints=checkpoints, rtol=rtol,
        loss=float(value), grad_reverse=np.asarray(g_rev).tolist(), grad_forward=np.asarray(g_fwd).tolist(),
        impacts=int(float(sol.impacts[0])), steps=int(sol.num_steps),
        ratio_reverse_over_forward=out["reverse_s"] / out["forward_s"],
        max_rel_diff_reverse_forward=float(np.max(np.abs(np.asarray(g_rev) - np.asarray(g_fwd))
                                                  / np.maximum(np.abs(np.asarray(g_fwd)), 1e-300))),
    )
    return out


def fit_time(name: str, optimizer=None, max_iter: int = 30):
    cfg = {"flores-slider-crank": (3.2e-3, 200e3, 20e3), "flores-2011-rig": (0.08, 50e3, 5e3)}[name]
    mech = jc.preset(name)
    k0, e0 = float(params.get(mech, "stiffness")), float(params.get(mech, "restitution"))
    sensor = Accelerometer(cfg[2])
    record = jc.synthetic_record(mech, cfg[0], cfg[1], sensor, snr_db=20, seed=0)
    start = {"stiffness": 3 * k0, "restitution": e0 - 0.3}
    runs = []
    for _ in range(2):
        with tempfile.TemporaryDirectory() as out:
            t = time.perf_counter()
            res = jc.fit(record, mech, start=start, sensor=sensor, out=out, progress=False, optimizer=optimizer,
                         max_iter=max_iter)
            runs.append((time.perf_counter() - t, res))
    (wall1, res), (wall2, res2) = runs
    return {
        "preset": name, "optimizer": res.settings["optimizer"], "record_s": cfg[0], "sample_rate_hz": cfg[1],
        "sensor_cutoff_hz": cfg[2], "window_s": res.window_length_s, "samples_fitted": res.n_samples,
        "wall_first_s": wall1, "wall_second_s": wall2, "iterations": res.iterations,
        "iterations_second": res2.iterations, "converged": res.converged, "loss": res.loss,
        "stiffness_error_pct": 100 * (res.estimates["stiffness"] / k0 - 1),
        "stiffness_std_pct": 100 * res.std["stiffness"] / k0,
        "restitution_error": res.estimates["restitution"] - e0, "restitution_std": res.std["restitution"],
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--revolutions", type=float, default=1.0, help="gradient window in crank revolutions (default 1)")
    p.add_argument("--params", type=int, default=3, help="number of parameters, 1..6 (default 3)")
    p.add_argument("--checkpoints", type=int, default=None, help="reverse-mode checkpoints (default: diffrax's)")
    p.add_argument("--repeats", type=int, default=3, help="steady-state repeats (median; default 3)")
    p.add_argument("--rtol", type=float, default=1e-8, help="integration rtol of the gradient runs (default 1e-8)")
    p.add_argument("--rig", action="store_true", help="also time the fit on the Flores 2011 rig")
    p.add_argument("--adam", action="store_true", help="also time the benchmark fit with adam (lr 0.05)")
    p.add_argument("--no-gradients", action="store_true", help="skip the gradient ratio")
    p.add_argument("--json", default=os.path.join(os.path.dirname(__file__), "results", "fit.json"))
    args = p.parse_args(argv)
    load0 = os.getloadavg()
    results = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version(),
                           "jax": jax.__version__, "backend": jax.default_backend(), "load_start": load0}}
    lines = []
    if not args.no_gradients:
        g = gradient_ratio(args.revolutions, args.params, args.checkpoints, args.repeats, args.rtol)
        results["gradient"] = g
        lines += [
            f"gradient of mean(slider_acc^2)/1e8 over {g['revolutions']:g} revolution(s) ({1e3 * g['window_s']:.1f} ms, "
            f"{g['impacts']} impacts, {g['steps']} steps, rtol {g['rtol']:g}) w.r.t. {', '.join(g['parameters'])}:",
            f"  primal            first {g['primal_first_s']:7.2f} s   steady {g['primal_s']:7.3f} s",
            f"  reverse (grad)    first {g['reverse_first_s']:7.2f} s   steady {g['reverse_s']:7.3f} s   "
            f"checkpoints {g['checkpoints']}",
            f"  forward (jacfwd)  first {g['forward_first_s']:7.2f} s   steady {g['forward_s']:7.3f} s",
            f"  reverse / forward = {g['ratio_reverse_over_forward']:.2f} (target <= 4); largest relative difference "
            f"between the two gradients {g['max_rel_diff_reverse_forward']:.1e}",
        ]
        print("\n".join(lines), flush=True)
    fits = [fit_time("flores-slider-crank")]
    if args.rig:
        fits.append(fit_time("flores-2011-rig"))
    if args.adam:
        fits.append(fit_time("flores-slider-crank", optimizer="adam:0.05", max_iter=120))
    results["fits"] = fits
    for f in fits:
        line = (f"fit {f['preset']} ({f['optimizer']}): first {f['wall_first_s']:.1f} s (with compilation), second "
                f"{f['wall_second_s']:.1f} s; {f['iterations']} iterations, converged {f['converged']}; stiffness "
                f"error {f['stiffness_error_pct']:+.3f} % (std {f['stiffness_std_pct']:.3f} %), restitution error "
                f"{f['restitution_error']:+.2e} (std {f['restitution_std']:.1e}), loss {f['loss']:.4g}")
        lines.append(line)
        print(line, flush=True)
    results["machine"]["load_end"] = os.getloadavg()
    lines.append(f"machine: {results['machine']['platform']}, {results['machine']['cpus']} CPUs, jax "
                 f"{jax.__version__} ({jax.default_backend()}), load average {load0[0]:.2f} at start, "
                 f"{results['machine']['load_end'][0]:.2f} at end")
    print(lines[-1])
    results["table"] = "\n".join(lines)
    os.makedirs(os.path.dirname(args.json), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump(results, f, indent=2)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
