"""Cost of the Lyapunov exponent from tangents against the time-series approach, on the benchmark
slider-crank (Flores et al., 0.5 mm clearance; jaxclear's preset ``flores-slider-crank``).

1. **One operating point** (``--speed-rpm``): the largest exponent by Benettin's method on the
   tangents (``jc.lyapunov``, ``count=1``) over ``--revolutions`` crank revolutions, its running
   estimate and batch-means standard error: how many revolutions 2 digits take (relative
   standard error 0.5 %) and what they cost.
2. **A map** of ``--points`` crank speeds between ``--rpm-low`` and ``--rpm-high``
   (``jc.lyapunov_map``, one compiled program over the rows, ``--map-revolutions`` each after
   one transient revolution): wall time, first call including compilation.
3. **The time-series approach on the same runs**: the same speeds simulated without tangents
   (one compiled program, 64 samples a revolution of the journal's eccentricity along x) and
   Rosenstein's estimate (``nolds.lyap_r``) on each series: wall time of both parts, and the
   estimates beside the tangent exponents.

4. **Convergence** (``--convergence``): the one point again reported every half revolution and at
   rtol 1e-8, each over the same ``--revolutions``: interval and tolerance independence (the
   tangents are renormalised at the end of every interval and within it as often as their growth
   asks, ``jaxclear.chaos.benettin``).

Writes ``results/chaos.json``. Small settings (``--quick``) keep it under 10 minutes on 2 shared
cores; the numbers then are costs, not converged exponents.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxclear as jc
from jaxclear import params
from jaxclear._storage import atomic_write_json
from jaxclear.chaos.signals import rosenstein

HERE = os.path.dirname(os.path.abspath(__file__))


def one_point(mech, revolutions: int, transient: int, fraction: float = 1.0, rtol: float = 1e-6,
              repeat: bool = True):
    """The largest exponent over ``revolutions`` after ``transient`` ones, reported every
    ``fraction`` of a revolution (renormalised at least as often), at ``rtol`` (atol = rtol / 1000); timed twice (first call with
    compilation, then steady) unless ``repeat`` is off (then both times are the one call's)."""
    period = jc.crank_period(mech)
    # max_steps is per renormalisation interval (about 5,000 steps a revolution at rtol 1e-8); the
    # margin of 4 million was needed before the tangents' tolerance grew with them (one interval
    # then stalled at the step floor) and is kept: it costs nothing where it is not used
    s = jc.settings((revolutions + transient) * period, throw=False, rtol=rtol, atol=rtol * 1e-3,
                    max_steps=4_000_000)
    kw = dict(interval=fraction * period, transient=transient * period, count=1, samples=4, keep=False)
    t = time.perf_counter()
    r = jc.lyapunov(mech, s, **kw)
    first = time.perf_counter() - t
    steady = first
    if repeat:
        t = time.perf_counter()
        r = jc.lyapunov(mech, s, **kw)
        steady = time.perf_counter() - t
    lam, se = float(r.exponents[0]), float(r.stderr[0])
    need = revolutions * (se / (0.005 * abs(lam))) ** 2 if lam else float("nan")
    return {"speed_rpm": float(params.get(mech, "speed_rpm")), "revolutions": revolutions,
            "interval_revolutions": fraction, "rtol": rtol, "exponent": lam,
            "stderr": se, "relative_stderr": se / abs(lam), "spread": float(r.spread[0]), "status": int(r.status),
            "run_status": int(r.run_status),
            "first_call_s": first, "steady_s": steady, "steady_s_per_revolution": steady / (revolutions + transient),
            "revolutions_for_2_digits": need,
            "time_for_2_digits_s": need * steady / (revolutions + transient)}


@eqx.filter_jit
def _series(mech, s, rpm):
    def member(v):
        m = params.replace(mech, "speed_rpm", v)
        sol = jc.simulate(m, s)
        return jc.channel(m, sol, "joint:0:ecc_x"), sol.status
    return jax.lax.map(member, rpm, batch_size=1)


def time_series(mech, rpm, revolutions: int, transient: int, samples: int = 64):
    """Plain runs at every speed (the same length in revolutions: the time grid is in crank
    angle, so each member's settings are its own period's); Rosenstein on each."""
    out, statuses = [], []
    # t_end is an array leaf and n_out the same for every speed: one compiled program, warmed up first
    def settings_at(v):
        period = jc.crank_period(params.replace(mech, "speed_rpm", float(v)))
        return jc.settings((revolutions + transient) * period, n_out=(revolutions + transient) * samples + 1,
                           throw=False), period

    t = time.perf_counter()
    jax.block_until_ready(_series(mech, settings_at(rpm[0])[0], jnp.asarray([rpm[0]])))
    t_first = time.perf_counter() - t
    t = time.perf_counter()
    for v in rpm:
        s, period = settings_at(v)
        x, st = _series(mech, s, jnp.asarray([v]))
        out.append((np.asarray(x[0])[transient * samples:], period / samples))
        statuses.append(int(st[0]))
    t_runs = time.perf_counter() - t
    t = time.perf_counter()
    est = []
    for x, dt in out:
        try:
            # the journal's eccentricity (the free motion); an e-folding time is a fraction of a
            # revolution, so the divergence is fitted over an eighth of one
            est.append(rosenstein(x, dt, emb_dim=4, min_tsep=samples, trajectory_len=samples // 8))
        except Exception as err:  # a series too short or flat: no estimate
            est.append(float("nan"))
            print("rosenstein:", err)
    t_ros = time.perf_counter() - t
    return {"first_run_s": t_first, "runs_s": t_runs, "rosenstein_s": t_ros, "estimates": est, "run_status": statuses}


def _write(result: dict, path: str) -> None:
    """The results so far, as JSON at ``path`` (its folder created; written atomically)."""
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    atomic_write_json(path, result, indent=1, sort_keys=False)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--speed-rpm", type=float, default=5000.0)
    ap.add_argument("--revolutions", type=int, default=100)
    ap.add_argument("--points", type=int, default=200)
    ap.add_argument("--map-revolutions", type=int, default=8)
    ap.add_argument("--rpm-low", type=float, default=2000.0)
    ap.add_argument("--rpm-high", type=float, default=6000.0)
    ap.add_argument("--series-points", type=int, default=None,
                    help="speeds of the time-series comparison (default: all --points)")
    ap.add_argument("--quick", action="store_true", help="small settings (under 10 minutes on 2 cores)")
    ap.add_argument("--only-point", action="store_true", help="the one operating point only (no map)")
    ap.add_argument("--convergence", action="store_true",
                    help="also the one point renormalised every half revolution and at rtol 1e-8 (same "
                    "revolutions; each call timed once); implies --only-point")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "chaos.json"))
    a = ap.parse_args()
    if a.quick:
        a.revolutions, a.map_revolutions, a.series_points = 40, 5, 20
    mech = jc.preset("flores-slider-crank", speed_rpm=a.speed_rpm)
    result = {"settings": vars(a), "device": jax.devices()[0].device_kind, "cores": os.cpu_count()}
    print("one point ...", flush=True)
    result["one_point"] = one = one_point(mech, a.revolutions, 1, repeat=not a.convergence)
    print(json.dumps(one, indent=1), flush=True)
    if a.convergence:  # the same point renormalised every half revolution, and at rtol 1e-8
        result["convergence"] = [one]
        for fraction, rtol in ((0.5, 1e-6), (1.0, 1e-8)):
            print(f"interval {fraction} revolution, rtol {rtol:g} ...", flush=True)
            result["convergence"].append(one_point(mech, a.revolutions, 1, fraction, rtol, repeat=False))
            print(json.dumps(result["convergence"][-1], indent=1), flush=True)
            _write(result, a.out)
        print("\ninterval [rev]  rtol    exponent [1/s]  standard error")
        for c in result["convergence"]:
            print(f"{c['interval_revolutions']:14g}  {c['rtol']:6g}  {c['exponent']:14.1f}  {c['stderr']:.1f} "
                  f"({100 * c['relative_stderr']:.2f} %)")

    if a.only_point or a.convergence:
        _write(result, a.out)
        print("written", a.out)
        return
    rpm = np.linspace(a.rpm_low, a.rpm_high, a.points)
    print(f"map of {a.points} speeds ...", flush=True)
    t = time.perf_counter()
    mp = jc.lyapunov_map(mech, jc.settings(1.0), ["speed_rpm"], rpm[:, None], revolutions=a.map_revolutions,
                         transient_revolutions=1, count=1, batch_size=1)
    lam = np.asarray(mp.exponents[:, 0])
    wall = time.perf_counter() - t
    t = time.perf_counter()
    jax.block_until_ready(jc.lyapunov_map(mech, jc.settings(1.0), ["speed_rpm"], rpm[:, None],
                                          revolutions=a.map_revolutions, transient_revolutions=1, count=1,
                                          batch_size=1).exponents)
    steady = time.perf_counter() - t
    result["map"] = {"points": a.points, "revolutions": a.map_revolutions, "first_call_s": wall, "steady_s": steady,
                     "per_point_s": steady / a.points, "exponents": lam.tolist(),
                     "status": np.asarray(mp.status).tolist(), "rpm": rpm.tolist()}
    print(f"  {wall:.1f} s (with compilation), {steady:.1f} s steady, {np.sum(np.asarray(mp.status) == 0)} ok",
          flush=True)

    k = a.series_points or a.points
    pick = np.linspace(0, a.points - 1, k).round().astype(int)
    print(f"time-series approach on {k} of the same speeds ...", flush=True)
    ts = time_series(mech, rpm[pick], a.map_revolutions, 1)
    ts["rpm"] = rpm[pick].tolist()
    ts["tangent_exponents"] = lam[pick].tolist()
    ts["per_point_s"] = (ts["runs_s"] + ts["rosenstein_s"]) / k
    result["time_series"] = ts
    print(json.dumps({x: ts[x] for x in ("runs_s", "rosenstein_s", "per_point_s")}), flush=True)
    _write(result, a.out)
    print("written", a.out)


if __name__ == "__main__":
    main()
