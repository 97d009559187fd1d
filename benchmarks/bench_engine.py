#!/usr/bin/env python
"""Engine benchmark: jaxclear against a plain NumPy/SciPy ``solve_ivp`` implementation of the same
model (``benchmarks/scipy_reference.py``), in one process run.

The benchmark run is the Flores slider-crank with a clearance in the rod-slider joint
(``jc.preset("flores-slider-crank")``: Lankarani-Nikravesh contact law, Ambrosio friction law,
c = 0.5 mm, 5000 rpm, c_r = 0.9) over 3 crank revolutions at rtol = 1e-6, atol = 1e-9.

Measured (all wall-clock, ``time.perf_counter``; JAX results are ``jax.block_until_ready``-ed):

* jaxclear first call in this fresh process (tracing + XLA compilation + one run) and steady-state
  time (median of ``--repeats`` calls of ``jc.simulate`` with the same structure);
  compile time = first call - steady-state median;
* SciPy ``solve_ivp`` (RK45, optionally DOP853) with the same tolerances, median of
  ``--scipy-repeats`` calls of ``scipy_reference.simulate``;
* steps, RHS evaluations, impacts, peak contact force and maximum penetration of both codes;
* the ideal (no clearance) mechanism of both codes, for context;
* a ``jax.vmap`` batch of ``--batch-size`` runs at different clearances (with
  ``Settings(stages="loop")``, the faster form under vmap) against the same runs made one after
  another with plain ``jc.simulate`` (unrolled stages, the fastest single-run path).

Run from the repository root::

    PYTHONPATH=. python benchmarks/bench_engine.py                 # defaults, writes JSON
    PYTHONPATH=. python benchmarks/bench_engine.py --dop853        # add a SciPy DOP853 column

See ``benchmarks/README.md`` for what every number means.
"""

from __future__ import annotations

import time

_T_PROCESS_START = time.perf_counter()  # before jax is imported

import argparse  # noqa: E402
import contextlib  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for _p in (str(ROOT), str(HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)

# new right-hand-side evaluations per step attempt of the explicit FSAL Runge-Kutta solvers
# (stages - 1); None: implicit solver, not estimated
NEW_STAGES_PER_STEP = {"tsit5": 6, "dopri5": 6, "dopri8": 13, "bosh3": 3, "kvaerno5": None}


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------
def _median(xs):
    return float(statistics.median(xs))


def first_impact(pen, force):
    """Peak force and penetration over the first contact episode seen on the output grid
    (first contiguous run of samples with penetration > 0). Returns (index, F_max, delta_max)."""
    pen = np.asarray(pen, dtype=float)
    force = np.asarray(force, dtype=float)
    inside = np.nan_to_num(pen, nan=-1.0) > 0.0
    if not inside.any():
        return None, 0.0, float("nan")
    i0 = int(np.argmax(inside))
    i1 = i0
    while i1 + 1 < len(inside) and inside[i1 + 1]:
        i1 += 1
    return i0, float(force[i0:i1 + 1].max()), float(pen[i0:i1 + 1].max())


class _ScipyStepCounter:
    """Counts SciPy Runge-Kutta step attempts (calls of ``rk_step``) and accepted steps."""

    def __init__(self):
        self.attempts = 0
        self.accepted = 0

    @contextlib.contextmanager
    def patched(self, method: str):
        """Yields a counting subclass of the SciPy method to pass as ``method=``; patches the
        module-level ``rk_step`` of scipy's RK module meanwhile (private API: if it moves,
        only the step counts are lost)."""
        from scipy.integrate._ivp import rk

        base = {"RK45": rk.RK45, "DOP853": rk.DOP853, "RK23": rk.RK23}[method]
        counter = self

        class Counted(base):
            def _step_impl(self):
                ok, msg = super()._step_impl()
                if ok:
                    counter.accepted += 1
                return ok, msg

        orig = getattr(rk, "rk_step", None)
        if orig is not None:
            def counting_rk_step(*a, **k):
                counter.attempts += 1
                return orig(*a, **k)

            rk.rk_step = counting_rk_step
        try:
            yield Counted
        finally:
            if orig is not None:
                rk.rk_step = orig
        if orig is None:
            self.attempts = None


def machine_info():
    import jax

    cpu_model = None
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu_model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    versions = {}
    for mod in ("jax", "jaxlib", "diffrax", "equinox", "numpy", "scipy"):
        try:
            versions[mod] = __import__(mod).__version__
        except Exception:  # pragma: no cover
            versions[mod] = None
    try:
        cache_dir = jax.config.jax_compilation_cache_dir
    except AttributeError:  # pragma: no cover
        cache_dir = None
    return {
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_model": cpu_model,
        "cpu_count": os.cpu_count(),
        "cpus_usable": usable,
        "python": platform.python_version(),
        "versions": versions,
        "jax_backend": jax.default_backend(),
        "jax_devices": [str(d) for d in jax.devices()],
        "jax_x64": bool(jax.config.jax_enable_x64),
        "jax_compilation_cache_dir": cache_dir,
        "XLA_FLAGS": os.environ.get("XLA_FLAGS"),
    }


# ----------------------------------------------------------------------------------------------
# jaxclear
# ----------------------------------------------------------------------------------------------
def jax_run_summary(sol, solver: str):
    steps = int(sol.num_steps)
    impacts = int(np.asarray(sol.memory.impacts)[-1].sum()) if sol.memory.impacts.shape[-1] else 0
    k = NEW_STAGES_PER_STEP.get(solver)
    rhs = None if k is None else k * steps + 1 + impacts  # FSAL: k new stages / attempt
    out = {
        "status": int(sol.status),
        "steps": steps,
        "accepted_steps": int(sol.num_accepted_steps),
        "rejected_steps": int(sol.num_rejected_steps),
        "rhs_evals_estimate": rhs,
        "impacts": impacts,
    }
    if sol.penetration.shape[-1]:
        pen = np.asarray(sol.penetration)[:, 0]
        fn = np.asarray(sol.normal_force)[:, 0]
        i0, f1, d1 = first_impact(pen, fn)
        out.update(
            peak_normal_force=float(fn.max()),
            max_penetration=float(pen.max()),
            first_contact_time=None if i0 is None else float(np.asarray(sol.ts)[i0]),
            first_impact_peak_force=f1,
            first_impact_max_penetration=d1,
        )
    return out


def time_jax(fn, repeats):
    """First call (compile + run) and ``repeats`` steady-state calls. Returns (result, first_s, times)."""
    import jax

    t0 = time.perf_counter()
    out = jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn())
        times.append(time.perf_counter() - t0)
    return out, first, times


# ----------------------------------------------------------------------------------------------
# SciPy
# ----------------------------------------------------------------------------------------------
def scipy_bench(ref, p, t_end, ts, rtol, atol, method, ideal, repeats):
    calls, integ = [], []
    res = None
    counter = _ScipyStepCounter()
    for _ in range(repeats):
        counter.attempts, counter.accepted = 0, 0
        with counter.patched(method) as cls:
            t0 = time.perf_counter()
            res = ref.simulate(p, t_end, ts=ts, rtol=rtol, atol=atol, method=cls, ideal=ideal)
            calls.append(time.perf_counter() - t0)
        integ.append(res["wall_s"])
    out = {
        "method": method,
        "repeats": repeats,
        "call_s": calls,
        "call_median_s": _median(calls),
        "integration_s": integ,
        "integration_median_s": _median(integ),
        "steps": counter.attempts,
        "accepted_steps": counter.accepted,
        "rejected_steps": None if counter.attempts is None else counter.attempts - counter.accepted,
        "rhs_evals": int(res["nfev"]),
        "impacts": None if ideal else int(res["n_impacts"]),
    }
    if not ideal:
        i0, f1, d1 = first_impact(res["delta"], res["F_N"])
        out.update(
            peak_normal_force=float(np.max(res["F_N"])),
            max_penetration=float(np.nanmax(res["delta"])),
            first_contact_time=None if i0 is None else float(ts[i0]),
            first_impact_peak_force=f1,
            first_impact_max_penetration=d1,
        )
    return out


# ----------------------------------------------------------------------------------------------
# --profile: where the first call and the steady-state step go (in a fresh child process)
# ----------------------------------------------------------------------------------------------
def profile_child(revolutions, rtol, atol, solver, n_out, loops=5000):
    """Split the first call of jc.simulate into its parts and time the pieces of one solver step.
    Must run in a fresh process (nothing compiled yet). Returns a dict."""
    import re

    import diffrax
    import jax
    import jax.numpy as jnp

    import jaxclear as jc
    import importlib

    jsolve = importlib.import_module("jaxclear.integrate._simulate")  # the module (the package exports the function)
    from jaxclear.integrate import check_assembly, compiler_options, UnrolledExplicitRK
    from jaxclear.integrate import flat_vector_field, spd_solve
    from jaxclear.integrate._system import MechanismSystem, system_field

    mech = jc.preset("flores-slider-crank")
    s = jc.settings(revolutions * jc.crank_period(mech), n_out=n_out, rtol=rtol, atol=atol, solver=solver)
    out = {}
    t0 = time.perf_counter()
    check_assembly(mech, s)  # eager checks: compiles assemble() on its own
    out["first_eager_checks_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    lowered = jsolve._simulate.lower(mech, s, None)
    out["trace_and_lower_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    lowered.compile()
    out["xla_compile_s"] = time.perf_counter() - t0

    y0 = jc.initial_state(mech, s).pack()  # the solver integrates the packed state vector
    args = (mech, s.baumgarte)
    opts = compiler_options()

    def per_iteration(body, carry, args=args):
        # the mechanism is an argument of the compiled loop, as in jc.simulate (a closed-over
        # mechanism would be constant-folded into the kernels and flatter the numbers)
        loop = jax.jit(lambda c, a: jax.lax.fori_loop(0, loops, lambda i, cc: body(i, cc, a), c),
                       compiler_options=opts)
        jax.block_until_ready(loop(carry, args))
        t0 = time.perf_counter()
        jax.block_until_ready(loop(carry, args))
        return (time.perf_counter() - t0) / loops

    def rhs_body(i, y, args):  # one vector-field evaluation per iteration, carried so it is not hoisted
        return y + 1e-12 * flat_vector_field(i * 1e-9, y, args)

    out["rhs_eval_s"] = per_iteration(rhs_body, y0)

    m = mech.n_constraints

    def solve_body(i, y, args):  # the m x m Schur-complement solve of the constraint forces alone
        a = jnp.eye(m) + 1e-3 * jnp.outer(jnp.arange(m, dtype=float), jnp.arange(m, dtype=float)) + 1e-9 * y[0]
        return y + 1e-12 * spd_solve(a, jnp.ones(m)).sum()

    out["constraint_solve_s"] = per_iteration(solve_body, y0)
    out["constraint_solve_size"] = m

    term = diffrax.ODETerm(system_field)
    system = MechanismSystem(mech, s.baumgarte)

    def step_time(inner, memory=True):  # one solver step (all stages + memory update), tiny dt
        wrapped = jc.ImpactMemorySolver(inner) if memory else inner
        state0 = wrapped.init(term, 0.0, 1e-8, y0, system)

        def step_body(i, carry, args):
            y, st = carry
            t = i * 1e-8
            y1, _, _, st1, _ = wrapped.step(term, t, t + 1e-8, y, args, st, False)
            return y1, st1

        return per_iteration(step_body, (y0, state0), system)

    out["solver_step_s"] = step_time(jsolve.solve._inner_solver(s))
    out["solver_step_no_memory_s"] = step_time(jsolve.solve._inner_solver(s), memory=False)

    # the whole benchmark run, per step attempt, in three variants measured interleaved (each
    # round runs every variant once, in turn): measured one after another, the first variant
    # came out slowest whichever it was (up to 2x on the shared 2-core machine)
    other = "loop" if isinstance(jsolve.solve._inner_solver(s), UnrolledExplicitRK) else "unrolled"
    out["other_stages"] = other
    variants = {"whole_run": s, "whole_run_no_onsets": dataclasses.replace(s, exact_onsets=False),
                "whole_run_other_stages": dataclasses.replace(s, stages=other)}
    steps, walls = {}, {k: [] for k in variants}
    for key, settings in variants.items():
        steps[key] = int(jax.block_until_ready(jc.simulate(mech, settings)).num_steps)
    for _ in range(9):
        for key, settings in variants.items():
            t0 = time.perf_counter()
            jax.block_until_ready(jc.simulate(mech, settings))
            walls[key].append(time.perf_counter() - t0)
    for key in variants:
        out[f"{key}_per_step_s"] = _median(walls[key]) / steps[key]
        out[f"{key}_steps"] = steps[key]

    hlo = jax.jit(flat_vector_field, compiler_options=opts).lower(0.0, y0, args).compile().as_text()
    out["rhs_hlo_fusions"] = len(re.findall(r"= \S+ fusion\(", hlo))
    out["rhs_hlo_custom_calls"] = len(re.findall(r"custom-call\(", hlo))
    out["rhs_hlo_instructions"] = sum(1 for line in hlo.splitlines() if " = " in line)
    return out


def run_profile_subprocess(args):
    import subprocess

    cmd = [sys.executable, str(Path(__file__).resolve()), "--_profile-child", "--revolutions", str(args.revolutions),
           "--rtol", str(args.rtol), "--atol", str(args.atol), "--solver", args.solver, "--n-out", str(args.n_out)]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


# ----------------------------------------------------------------------------------------------
# table
# ----------------------------------------------------------------------------------------------
def _fmt(v, kind="g"):
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    if kind == "s":
        return f"{v:.3f} s"
    if kind == "ms":
        return f"{v * 1e3:.1f} ms"
    if kind == "us":
        return f"{v * 1e6:.1f} us"
    if kind == "int":
        return f"{int(v):d}"
    if kind == "e":
        return f"{v:.4e}"
    if kind == "x":
        return f"{v:.1f}x"
    return f"{v:g}"


def _approx(n):
    return "-" if n is None else "~" + _fmt(n, "int")


def table(title, header, rows):
    """rows: list of (label, [cells...]) or a plain string (a note line)."""
    w0 = max([len(r[0]) for r in rows if not isinstance(r, str)] + [len(header[0])])
    ncol = len(header) - 1
    widths = [len(h) for h in header[1:]]
    for r in rows:
        if isinstance(r, str):
            continue
        for j, c in enumerate(r[1]):
            widths[j] = max(widths[j], len(c))
    lines = [title, "=" * len(title)]
    lines.append(header[0].ljust(w0) + "".join("  " + h.rjust(w) for h, w in zip(header[1:], widths)))
    lines.append("-" * (w0 + sum(w + 2 for w in widths)))
    for r in rows:
        if isinstance(r, str):
            lines.append(r)
            continue
        cells = list(r[1]) + [""] * (ncol - len(r[1]))
        lines.append(r[0].ljust(w0) + "".join("  " + c.rjust(w) for c, w in zip(cells, widths)))
    return "\n".join(lines)


# ----------------------------------------------------------------------------------------------
# main
# ----------------------------------------------------------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--revolutions", type=float, default=3.0, help="crank revolutions (default 3)")
    ap.add_argument("--rtol", type=float, default=1e-6, help="relative tolerance, both codes (default 1e-6)")
    ap.add_argument("--atol", type=float, default=1e-9, help="absolute tolerance, both codes (default 1e-9)")
    ap.add_argument("--repeats", type=int, default=5, help="steady-state repeats of jaxclear (default 5)")
    ap.add_argument("--scipy-repeats", type=int, default=3, help="repeats of the SciPy runs (default 3)")
    ap.add_argument("--solver", default="tsit5", help="jaxclear solver (default tsit5)")
    ap.add_argument("--n-out", type=int, default=1001,
                    help="output samples on [0, t_end], same grid for both codes (default 1001)")
    ap.add_argument("--dop853", action="store_true", help="also run SciPy DOP853")
    ap.add_argument("--batch-size", type=int, default=8, help="vmap batch size (default 8; 0 skips)")
    ap.add_argument("--batch-repeats", type=int, default=2,
                    help="repeats of the vmap batch and of the serial loop (default 2)")
    ap.add_argument("--no-ideal", action="store_true", help="skip the ideal-mechanism rows")
    ap.add_argument("--json", default=str(HERE / "results" / "engine.json"),
                    help="where to write the JSON results (default benchmarks/results/engine.json)")
    ap.add_argument("--profile", action="store_true",
                    help="also split the first call and time one RHS evaluation / one solver step "
                         "(fresh child process, ~20 s more)")
    ap.add_argument("--_profile-child", dest="profile_child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.profile_child:
        import jaxclear  # noqa: F401  (float64)
        print(json.dumps(profile_child(args.revolutions, args.rtol, args.atol, args.solver, args.n_out)))
        return None
    load_start = os.getloadavg() if hasattr(os, "getloadavg") else None

    # --- imports (timed: part of what a user pays in a fresh process) -------------------------
    t0 = time.perf_counter()
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    import jaxclear as jc
    import importlib

    jsolve = importlib.import_module("jaxclear.integrate._simulate")  # the module (the package exports the function)
    from jaxclear.integrate import check_assembly, compiler_options, UnrolledExplicitRK
    import scipy_reference as ref

    import_s = time.perf_counter() - t0
    if args.solver not in jc.SOLVERS:
        ap.error(f"unknown solver {args.solver!r}; valid: {sorted(jc.SOLVERS)}")

    info = machine_info()
    if info["jax_compilation_cache_dir"]:
        print(f"WARNING: JAX persistent compilation cache enabled ({info['jax_compilation_cache_dir']}); "
              "the first-call/compile numbers may be cache hits", file=sys.stderr)

    # --- setup ----------------------------------------------------------------------------------
    t0 = time.perf_counter()
    mech = jc.preset("flores-slider-crank")
    period = jc.crank_period(mech)
    t_end = args.revolutions * period
    s = jc.settings(t_end, n_out=args.n_out, rtol=args.rtol, atol=args.atol, solver=args.solver)
    setup_s = time.perf_counter() - t0
    joint = mech.clearance_joints[0]
    ts = np.linspace(0.0, t_end, args.n_out)
    p = ref.params()
    # the reference's numbers must be this preset's numbers
    assert abs(p["R_B"] - float(joint.bearing_radius)) < 1e-15
    assert abs(p["R_J"] - float(joint.journal_radius)) < 1e-15
    assert abs(p["mu"] - float(joint.friction.coefficient)) < 1e-15
    assert abs(p["omega"] - 2 * np.pi / period) < 1e-9

    progress = lambda msg: print(f"[{time.perf_counter() - _T_PROCESS_START:7.1f} s] {msg}",  # noqa: E731
                                 file=sys.stderr, flush=True)

    # --- jaxclear, clearance: the first jaxclear call of this process ---------------------------
    progress("jaxclear clearance run: first call (compiles) ...")
    sol, first_s, times = time_jax(lambda: jc.simulate(mech, s), args.repeats)
    if int(sol.status) != 0:
        raise SystemExit(f"jaxclear run failed: status {int(sol.status)}")
    jx = jax_run_summary(sol, args.solver)
    steady = _median(times)
    jx.update(first_call_s=first_s, steady_s=times, steady_median_s=steady, compile_s=first_s - steady)
    # eager input checks inside jc.simulate (check_assembly), part of the steady-state time
    chk = []
    for _ in range(max(args.repeats, 3)):
        t0 = time.perf_counter()
        check_assembly(mech, s)
        chk.append(time.perf_counter() - t0)
    jx["eager_checks_median_s"] = _median(chk)

    # --- jaxclear, ideal --------------------------------------------------------------------------
    jx_ideal = None
    if not args.no_ideal:
        progress("jaxclear ideal run ...")
        mech_i = jc.preset("flores-slider-crank", ideal=True)
        sol_i, first_i, times_i = time_jax(lambda: jc.simulate(mech_i, s), args.repeats)
        jx_ideal = jax_run_summary(sol_i, args.solver)
        jx_ideal.update(first_call_s=first_i, steady_s=times_i, steady_median_s=_median(times_i),
                        compile_s=first_i - _median(times_i))

    # --- SciPy --------------------------------------------------------------------------------------
    methods = ["RK45"] + (["DOP853"] if args.dop853 else [])
    sp, sp_ideal = {}, {}
    for m in methods:
        progress(f"SciPy {m} clearance run x{args.scipy_repeats} ...")
        sp[m] = scipy_bench(ref, p, t_end, ts, args.rtol, args.atol, m, False, args.scipy_repeats)
        if not args.no_ideal:
            progress(f"SciPy {m} ideal run x{args.scipy_repeats} ...")
            sp_ideal[m] = scipy_bench(ref, p, t_end, ts, args.rtol, args.atol, m, True, args.scipy_repeats)

    # --- vmap batch vs serial ---------------------------------------------------------------------
    batch = None
    if args.batch_size > 0:
        n = args.batch_size
        R_B = float(joint.bearing_radius)
        cs = np.linspace(0.25e-3, 1.0e-3, n) if n > 1 else np.array([0.5e-3])

        def with_clearance(c):
            # jnp.asarray: a Python float here would become a static leaf for filter_jit and
            # recompile the serial runs once per clearance value
            return eqx.tree_at(lambda m: m.clearance_joints[0].journal_radius, mech,
                               jnp.asarray(R_B - c, dtype=float))

        # batches integrate with diffrax's stage loop (faster under vmap, as sweeps do); the serial
        # runs below are plain jc.simulate calls (unrolled stages, the fastest single-run path)
        s_batch = dataclasses.replace(s, stages="loop")
        batched = jax.jit(jax.vmap(lambda c: jc.simulate(with_clearance(c), s_batch)),
                          compiler_options=jc.integrate.compiler_options())
        cs_j = jnp.asarray(cs)
        progress(f"vmap batch of {n}: first call (compiles) ...")
        bsol, bfirst, btimes = time_jax(lambda: batched(cs_j), args.batch_repeats)
        b_steps = np.asarray(bsol.num_steps).astype(int)
        b_status = np.asarray(bsol.status).astype(int)
        b_impacts = np.asarray(bsol.memory.impacts)[:, -1, 0].astype(int)

        progress(f"{n} serial runs x{args.batch_repeats} ...")
        serial_times, serial_steps, serial_impacts, serial_each = [], [], [], []
        mechs = [with_clearance(float(c)) for c in cs]
        for _ in range(args.batch_repeats):
            t_all = time.perf_counter()
            steps_r, imp_r, each = [], [], []
            for m in mechs:  # same structure as the benchmark run: no recompilation
                t0 = time.perf_counter()
                r = jax.block_until_ready(jc.simulate(m, s))
                each.append(time.perf_counter() - t0)
                steps_r.append(int(r.num_steps))
                imp_r.append(int(np.asarray(r.memory.impacts)[-1, 0]))
            serial_times.append(time.perf_counter() - t_all)
            serial_steps, serial_impacts, serial_each = steps_r, imp_r, each
        b_med, s_med = _median(btimes), _median(serial_times)
        batch = {
            "size": n,
            "clearances_m": cs.tolist(),
            "vmap_first_call_s": bfirst,
            "vmap_s": btimes,
            "vmap_median_s": b_med,
            "vmap_compile_s": bfirst - b_med,
            "vmap_steps": b_steps.tolist(),
            "vmap_impacts": b_impacts.tolist(),
            "vmap_status": b_status.tolist(),
            "serial_s": serial_times,
            "serial_median_s": s_med,
            "serial_each_s": serial_each,
            "serial_steps": serial_steps,
            "serial_impacts": serial_impacts,
            "per_sim_vmap_s": b_med / n,
            "per_sim_serial_s": s_med / n,
            "speedup": s_med / b_med,
            # the batched while loop runs max(steps) iterations, every member doing work in each
            "vmap_s_per_loop_iteration": b_med / int(b_steps.max()),
            "vmap_s_per_member_step": b_med / (n * int(b_steps.max())),
            "serial_s_per_step": s_med / int(sum(serial_steps)),
        }

    prof = None
    if args.profile:
        progress("profile (fresh child process) ...")
        prof = run_profile_subprocess(args)

    load_end = os.getloadavg() if hasattr(os, "getloadavg") else None
    total_s = time.perf_counter() - _T_PROCESS_START

    # --- table ----------------------------------------------------------------------------------
    rk = sp["RK45"]
    ratio_call = rk["call_median_s"] / jx["steady_median_s"]
    ratio_integ = rk["integration_median_s"] / jx["steady_median_s"]
    header = ["", f"jaxclear {args.solver}"] + [f"SciPy {m}" for m in methods]

    def sp_cells(key, kind):
        return [_fmt(sp[m].get(key), kind) for m in methods]

    rows = [
        ("import jax + jaxclear", [_fmt(import_s, "s")] + ["-"] * len(methods)),
        ("first call (fresh process)", [_fmt(jx["first_call_s"], "s")] + ["-"] * len(methods)),
        ("compile = first - steady", [_fmt(jx["compile_s"], "s")] + ["0 (none)"] * len(methods)),
        (f"steady-state, median of {args.repeats}/{args.scipy_repeats}",
         [_fmt(jx["steady_median_s"], "s")] + sp_cells("call_median_s", "s")),
        ("  integration only (SciPy)", ["-"] + sp_cells("integration_median_s", "s")),
        ("  eager input checks (jaxclear)", [_fmt(jx["eager_checks_median_s"], "ms")] + ["-"] * len(methods)),
        ("step attempts", [_fmt(jx["steps"], "int")] + sp_cells("steps", "int")),
        ("  accepted", [_fmt(jx["accepted_steps"], "int")] + sp_cells("accepted_steps", "int")),
        ("  rejected", [_fmt(jx["rejected_steps"], "int")] + sp_cells("rejected_steps", "int")),
        ("RHS evaluations", [_approx(jx["rhs_evals_estimate"])] + sp_cells("rhs_evals", "int")),
        ("wall per RHS evaluation",
         [_fmt(None if jx["rhs_evals_estimate"] is None else jx["steady_median_s"] / jx["rhs_evals_estimate"], "us")]
         + [_fmt(sp[m]["integration_median_s"] / sp[m]["rhs_evals"], "us") for m in methods]),
        ("impacts (contact onsets)", [_fmt(jx["impacts"], "int")] + sp_cells("impacts", "int")),
        ("first contact at (grid time)", [_fmt(jx["first_contact_time"], "e") + " s"]
         + [_fmt(sp[m]["first_contact_time"], "e") + " s" for m in methods]),
        ("first impact: peak F_N [N]", [_fmt(jx["first_impact_peak_force"], "e")]
         + sp_cells("first_impact_peak_force", "e")),
        ("first impact: max delta [m]", [_fmt(jx["first_impact_max_penetration"], "e")]
         + sp_cells("first_impact_max_penetration", "e")),
        ("whole run: peak F_N [N]", [_fmt(jx["peak_normal_force"], "e")] + sp_cells("peak_normal_force", "e")),
        ("whole run: max delta [m]", [_fmt(jx["max_penetration"], "e")] + sp_cells("max_penetration", "e")),
    ]
    if jx_ideal is not None:
        rows += [
            "ideal mechanism (no clearance), for context:",
            ("  first call", [_fmt(jx_ideal["first_call_s"], "s")] + ["-"] * len(methods)),
            ("  compile = first - steady", [_fmt(jx_ideal["compile_s"], "s")] + ["-"] * len(methods)),
            ("  steady-state", [_fmt(jx_ideal["steady_median_s"], "s")]
             + [_fmt(sp_ideal[m]["call_median_s"], "s") for m in methods]),
            ("  step attempts", [_fmt(jx_ideal["steps"], "int")] + [_fmt(sp_ideal[m]["steps"], "int") for m in methods]),
            ("  RHS evaluations", [_approx(jx_ideal["rhs_evals_estimate"])]
             + [_fmt(sp_ideal[m]["rhs_evals"], "int") for m in methods]),
        ]
    title = (f"jaxclear vs SciPy: flores-slider-crank (LN + Ambrosio, mu = {float(joint.friction.coefficient):g}), "
             f"{args.revolutions:g} rev (t_end = {t_end:.4f} s), rtol {args.rtol:g}, atol {args.atol:g}, "
             f"{args.n_out} output samples")
    text = [table(title, header, rows), ""]
    text.append("speed-up after compilation (SciPy RK45 steady state / jaxclear steady state):")
    text.append(f"  SciPy whole call        {ratio_call:6.1f}x  (both calls return forces/penetrations on the grid)")
    text.append(f"  SciPy integration only  {ratio_integ:6.1f}x  (SciPy output post-processing excluded; "
                "used for the target)")
    met = lambda ok: "met" if ok else "NOT met"  # noqa: E731
    text.append(f"targets: >= 30x after compilation: {met(ratio_integ >= 30)};  "
                f"compile < 10 s: {met(jx['compile_s'] < 10)} ({jx['compile_s']:.1f} s)")
    if batch is not None:
        bh = ["", f"vmap batch of {batch['size']} (loop)", f"{batch['size']} serial runs"]
        brows = [
            ("first call", [_fmt(batch["vmap_first_call_s"], "s"), "- (compiled above)"]),
            ("compile = first - steady", [_fmt(batch["vmap_compile_s"], "s"), "-"]),
            (f"wall, median of {args.batch_repeats}", [_fmt(batch["vmap_median_s"], "s"), _fmt(batch["serial_median_s"], "s")]),
            ("wall per simulation", [_fmt(batch["per_sim_vmap_s"], "s"), _fmt(batch["per_sim_serial_s"], "s")]),
            ("step attempts: total", [_fmt(int(sum(batch["vmap_steps"])), "int"), _fmt(int(sum(batch["serial_steps"])), "int")]),
            ("step attempts: max over runs", [_fmt(max(batch["vmap_steps"]), "int"), _fmt(max(batch["serial_steps"]), "int")]),
            ("wall per step of one run", [_fmt(batch["vmap_s_per_member_step"], "us") + " (a)",
                                          _fmt(batch["serial_s_per_step"], "us")]),
            ("wall per batched loop iteration", [_fmt(batch["vmap_s_per_loop_iteration"], "us"), "-"]),
        ]
        btitle = (f"vmap over {batch['size']} clearances c = {batch['clearances_m'][0] * 1e3:g} ... "
                  f"{batch['clearances_m'][-1] * 1e3:g} mm vs the same runs one after another")
        text += ["", table(btitle, bh, brows)]
        text.append(f"batching speed-up (serial / vmap wall): {batch['speedup']:.2f}x")
        text.append("steps per run, vmap  : " + " ".join(str(v) for v in batch["vmap_steps"]))
        text.append("steps per run, serial: " + " ".join(str(v) for v in batch["serial_steps"]))
        text.append("(a) vmap wall / (batch size x max steps): the batched loop runs until its slowest member is done")
    if prof is not None:
        k = NEW_STAGES_PER_STEP.get(args.solver)
        per_step = jx["steady_median_s"] / jx["steps"]
        prow = [
            ("first call, split (fresh child process):", []),
            ("  eager input checks (compile assemble + run)", [_fmt(prof["first_eager_checks_s"], "s")]),
            ("  trace + lower _simulate to XLA", [_fmt(prof["trace_and_lower_s"], "s")]),
            ("  XLA compile", [_fmt(prof["xla_compile_s"], "s")]),
            ("steady state, per step attempt:", []),
            ("  whole run: steady / step attempts", [_fmt(per_step, "us")]),
            ("  whole run in the profile process (interleaved, median of 9)",
             [_fmt(prof["whole_run_per_step_s"], "us") + f" x {prof['whole_run_steps']}"]),
            ("  whole run without exact onsets",
             [_fmt(prof["whole_run_no_onsets_per_step_s"], "us") + f" x {prof['whole_run_no_onsets_steps']}"]),
            ("  one solver step in a fori_loop (stages + memory)", [_fmt(prof["solver_step_s"], "us")]),
            ("  the same without the memory update", [_fmt(prof["solver_step_no_memory_s"], "us")]),
            (f"  whole run with stages='{prof['other_stages']}'",
             [_fmt(prof["whole_run_other_stages_per_step_s"], "us") + f" x {prof['whole_run_other_stages_steps']}"]),
            (f"  {k} x one RHS evaluation" if k else "  one RHS evaluation",
             [_fmt(prof["rhs_eval_s"] * (k or 1), "us")]),
            ("  one RHS evaluation", [_fmt(prof["rhs_eval_s"], "us")]),
            (f"  of which the {prof['constraint_solve_size']}x{prof['constraint_solve_size']} constraint-force solve",
             [_fmt(prof["constraint_solve_s"], "us")]),
            ("  RHS as compiled: XLA fusions / LAPACK custom calls",
             [f"{prof['rhs_hlo_fusions']} / {prof['rhs_hlo_custom_calls']}"]),
        ]
        prow = [r if r[1] else r[0] for r in prow]
        text += ["", table("profile (jaxclear)", ["", "time"], prow)]
    text.append("")
    if load_start is not None:
        # at the start the 1-min load is other processes' (this one has barely begun); at the end
        # it includes this script's own work
        text.append(f"load average (1 min) at start / end: {load_start[0]:.2f} / {load_end[0]:.2f}"
                    + ("  -- WARNING: the machine was busy when the benchmark started; times may be inflated"
                       if load_start[0] > 0.5 * (info["cpus_usable"] or 1) else ""))
    text.append(f"machine: {info['platform']}, {info['cpu_model']}, {info['cpus_usable']} usable CPUs "
                f"(cpu_count {info['cpu_count']}); jax {info['versions']['jax']} on {info['jax_devices']}; "
                f"{info['date_utc']}; whole script {total_s:.0f} s")
    report = "\n".join(text)
    print(report)

    results = {
        "benchmark": "flores-slider-crank clearance, jaxclear vs scipy solve_ivp",
        "config": {
            "revolutions": args.revolutions, "t_end_s": t_end, "rtol": args.rtol, "atol": args.atol,
            "solver": args.solver, "n_out": args.n_out, "repeats": args.repeats,
            "scipy_repeats": args.scipy_repeats, "friction_coefficient": float(joint.friction.coefficient),
            "clearance_m": float(joint.clearance), "restitution": p["c_r"],
        },
        "machine": info,
        "import_s": import_s,
        "setup_s": setup_s,
        "jaxclear": jx,
        "jaxclear_ideal": jx_ideal,
        "scipy": sp,
        "scipy_ideal": sp_ideal or None,
        "ratio_scipy_call_over_jaxclear": ratio_call,
        "ratio_scipy_integration_over_jaxclear": ratio_integ,
        "targets": {"speedup_30x_met": bool(ratio_integ >= 30), "compile_under_10s_met": bool(jx["compile_s"] < 10)},
        "batch": batch,
        "profile": prof,
        "load_average_start": load_start,
        "load_average_end": load_end,
        "script_total_s": total_s,
        "table": report,
    }
    path = Path(args.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=2) + "\n")
    progress(f"wrote {path}")
    return results


if __name__ == "__main__":
    main()
