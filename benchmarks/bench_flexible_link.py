"""The clearance joint on a flexible connecting rod (issue 43, items 4 and 6): the Flores benchmark
slider-crank (``jc.preset("flores-slider-crank")``: 0.5 mm radial clearance in the rod-slider
joint, 5000 rpm) with its rod rigid, made of steel as built, and ten times softer, each flexible
rod with 4 and 8 rigid finite elements (``jc.flexible_link``).

The rod as built: the preset's rod (0.12 m between its joints, 0.21 kg) taken as a solid circular
steel bar of that mass (rho = 7800 kg/m^3: A = m / (rho L) = 2.24e-4 m^2, d = 16.9 mm,
I = pi d^4 / 64 = 4.0e-9 m^4, E = 207 GPa); its first bending frequency pinned-pinned,
pi^2 / L^2 sqrt(EI / mu), is 14,900 rad/s (2.4 kHz), of the order of the contact's own
(k_eff = 1.5 K delta^0.5 against the slider's mass: about 17,000 rad/s at 7 um of penetration).
Ten times softer: 4,700 rad/s.

Each rod undamped with 4 and 8 elements, and with 4 elements and Kelvin-Voigt damping of
``--zeta`` (2 %) of critical in its first bending mode (steel's structural damping is 0.1-2 %).
Each run: ``--revolutions`` crank revolutions at rtol 1e-6 / atol 1e-9 (the benchmark's
tolerances), compiled once, then timed (median of ``--repeats``). Reported over the last
``--measured`` revolutions (the start-up's transient left out): the largest contact force and
the mean of each revolution's largest, the impacts (onsets of contact) a revolution, the slider's peak and RMS acceleration, the rod's midpoint
deflection (from the chord through its ends) and largest bending moment; and the cost: compile,
steady time, solver steps, against the rigid rod.

``--fit`` also fits the contact stiffness and restitution through the flexible rod (item 7).
``--implicit`` also runs the damped steel rod (4 elements) with diffrax's implicit Kvaerno5 against
Tsit5 (item 4: how far each gets in at most 100,000 steps of a twentieth of a revolution).

Usage: python benchmarks/bench_flexible_link.py [--revolutions 5] [--measured 3] [--zeta 0.02] [--repeats 3] [--fit] [--implicit] [--json PATH]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

import jaxclear as jc
from _timing import compile_and_steady
from jaxclear._storage import atomic_write_json

HERE = Path(__file__).resolve().parent
RHO, E_STEEL = 7800.0, 207e9  # kg/m^3, Pa


def rod_length(mech) -> float:
    """The preset rod's length between its joints A and B [m]."""
    rod = mech.body("rod")
    return float(np.linalg.norm(np.asarray(rod.points["B"]) - np.asarray(rod.points["A"])))


def rod_section(mech) -> tuple[float, float]:
    """``(A, I)`` of a solid circular steel bar with the preset rod's mass and length."""
    area = float(mech.body("rod").mass) / (RHO * rod_length(mech))
    diameter = np.sqrt(4 * area / np.pi)
    return area, float(np.pi * diameter**4 / 64)


def first_frequency(mech, modulus: float) -> float:
    """The rod's first bending frequency pinned-pinned [rad/s], Euler-Bernoulli."""
    area, second = rod_section(mech)
    return float(np.pi**2 / rod_length(mech) ** 2 * np.sqrt(modulus * second / (RHO * area)))


def cases(mech, zeta: float):
    """``(label, E, elements, eta, mechanism)``: the rigid rod, then each rod undamped with 4 and 8
    elements and damped (``zeta`` of critical in its first bending mode: eta = 2 zeta / omega_1)
    with 4."""
    _, second = rod_section(mech)
    out = [("rigid rod", None, 0, 0.0, mech)]
    for label, factor in (("steel rod as built", 1.0), ("ten times softer", 0.1)):
        modulus = E_STEEL * factor
        eta = 2 * zeta / first_frequency(mech, modulus)
        for m, damping in ((4, 0.0), (8, 0.0), (4, eta)):
            out.append((label, modulus, m, damping, jc.flexible_link(mech, "rod", youngs_modulus=modulus, second_moment=second,
                                                                     elements=m, damping=damping)))
    return out


def measure(mech, s, repeats: int, last_from: float, period: float) -> dict:
    sol, first, steady = compile_and_steady(mech, s, repeats)
    t = np.asarray(sol.ts)
    keep = t >= last_from
    force = np.asarray(jc.channel(mech, sol, "joint:0:normal_force"))
    acc = np.asarray(jc.channel(mech, sol, "body:slider:x:acc"))
    contact = force > 0.0
    revolution = np.floor((t[keep] - last_from) / period + 1e-9).astype(int)
    per_revolution = [force[keep][revolution == k].max() for k in np.unique(revolution) if np.sum(revolution == k) > 1]
    row = {"first_s": first, "steady_s": steady, "steps": int(sol.num_steps),
           "max_contact_force_N": float(force[keep].max()),
           "mean_revolution_max_force_N": float(np.mean(per_revolution)),
           "impacts_per_revolution": float(np.sum(contact[keep][1:] & ~contact[keep][:-1]) / len(per_revolution)),
           "slider_acc_peak": float(np.abs(acc[keep]).max()), "slider_acc_rms": float(np.sqrt(np.mean(acc[keep] ** 2)))}
    if any(isinstance(ld, jc.DiscreteBeam) for ld in mech.loads):
        deflection = np.asarray(jc.channel(mech, sol, "load:rod:deflection"))[keep]
        row.update(deflection_min_um=float(deflection.min() * 1e6), deflection_max_um=float(deflection.max() * 1e6),
                   moment_max_Nm=float(np.asarray(jc.channel(mech, sol, "load:rod:moment_max"))[keep].max()))
    return row


def fit_through_the_link(mech) -> dict:
    """Item 7: contact stiffness and restitution fitted from a record of the flexible mechanism
    (steel rod, 4 elements, 2 % damping; truth 0.8 K_Hertz, c_r 0.75; ``jc.synthetic_record``:
    1.2 ms from start-up, 50 kHz, 10 kHz accelerometer, 20 dB noise) with the same mechanism."""
    _, second = rod_section(mech)
    flex = jc.flexible_link(mech, "rod", youngs_modulus=E_STEEL, second_moment=second, elements=4,
                            damping=2 * 0.02 / first_frequency(mech, E_STEEL))
    truth = jc.params.replace_many(flex, {"stiffness": 0.8 * float(jc.params.get(flex, "stiffness")), "restitution": 0.75})
    record = jc.synthetic_record(truth, 1.2e-3, 50e3, sensor=jc.Accelerometer(10e3), snr_db=20.0, seed=4)
    t0 = time.perf_counter()
    res = jc.fit(record, flex, free=["stiffness", "restitution"], sensor=jc.Accelerometer(10e3), progress=False)
    out = {"fit_s": time.perf_counter() - t0, "ok": res.ok, "iterations": res.iterations}
    for name in ("stiffness", "restitution"):
        true = float(jc.params.get(truth, name))
        out[name] = {"true": true, "estimate": res.estimates[name], "std": res.std[name]}
        print(f"fit through the link: {name} true {true:.6g}, estimate {res.estimates[name]:.6g} +- "
              f"{res.std[name]:.3g} ({(res.estimates[name] - true) / res.std[name]:+.2f} std)", flush=True)
    print(f"fit through the link: {out['fit_s']:.0f} s, {res.iterations} iterations, ok {res.ok}", flush=True)
    return out


def implicit_against_explicit(mech, zeta: float) -> list[dict]:
    """Item 4: the damped steel rod (4 elements) over a twentieth of a revolution (0.6 ms), at
    most 100,000 steps, by Tsit5 (rtol 1e-6) and Kvaerno5 (rtol 1e-6 and 1e-4): steps accepted
    and rejected, the time reached, the first call (compilation included) and a second one."""
    _, second = rod_section(mech)
    flex = jc.flexible_link(mech, "rod", youngs_modulus=E_STEEL, second_moment=second, elements=4,
                            damping=2 * zeta / first_frequency(mech, E_STEEL))
    span = 0.05 * float(jc.crank_period(mech))
    rows = []
    for solver, rtol in (("tsit5", 1e-6), ("kvaerno5", 1e-6), ("kvaerno5", 1e-4)):
        s = jc.settings(t_end=span, n_out=101, solver=solver, rtol=rtol, atol=1e-9, max_steps=100_000, throw=False)
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            sol = jc.simulate(flex, s)
            steps = int(sol.num_steps)  # waits for the run
            times.append(time.perf_counter() - t0)
        finite = np.isfinite(np.asarray(sol.q)[:, 0])  # a run that stopped has no samples after its stop
        reached = span if sol.ok else float(np.asarray(sol.ts)[finite][-1])
        row = {"solver": solver, "rtol": rtol, "steps": steps, "accepted": int(sol.num_accepted_steps),
               "rejected": int(sol.num_rejected_steps), "ok": bool(sol.ok), "span_s": span,
               "reached_s": reached, "first_s": times[0], "second_s": times[1]}
        rows.append(row)
        print(f"implicit: {solver:<9} rtol {rtol:.0e}: {steps} steps ({row['rejected']} rejected), "
              f"{'reached t_end' if sol.ok else 'stopped'}; first {times[0]:.1f} s, second {times[1]:.2f} s", flush=True)
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--revolutions", type=int, default=5)
    p.add_argument("--measured", type=int, default=3, help="the last revolutions measured (default 3)")
    p.add_argument("--zeta", type=float, default=0.02, help="damping ratio of the damped rods' first mode (default 0.02)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--samples-per-revolution", type=int, default=2000)
    p.add_argument("--fit", action="store_true", help="also fit contact stiffness and restitution through the "
                   "flexible rod (about 20 minutes on 2 cores)")
    p.add_argument("--implicit", action="store_true", help="also run the damped steel rod with the implicit "
                   "Kvaerno5 against Tsit5 (a few minutes)")
    p.add_argument("--json", default=str(HERE / "results" / "flexible_link.json"))
    args = p.parse_args(argv)
    mech = jc.preset("flores-slider-crank")
    period = jc.crank_period(mech)
    s = jc.settings(t_end=args.revolutions * period, n_out=args.revolutions * args.samples_per_revolution + 1)
    rows = []
    print(f"{'rod':<20}{'E [GPa]':>8}{'m':>3}{'zeta':>6}{'first s':>8}{'steady s':>9}{'steps':>7}{'F max kN':>9}"
          f"{'F/rev kN':>9}{'imp/rev':>8}{'a peak':>9}{'a rms':>8}{'defl um':>14}{'M max':>7}", flush=True)
    for label, modulus, m, eta, mm in cases(mech, args.zeta):
        zeta = 0.0 if modulus is None else 0.5 * eta * first_frequency(mech, modulus)
        row = {"rod": label, "youngs_modulus_Pa": modulus, "elements": m, "damping_s": eta, "zeta_first_mode": zeta,
               **measure(mm, s, args.repeats, (args.revolutions - args.measured) * period, period)}
        rows.append(row)
        defl = (f"[{row['deflection_min_um']:.0f}, {row['deflection_max_um']:.0f}]" if "deflection_min_um" in row else "")
        print(f"{label:<20}{(modulus or 0) / 1e9:>8.1f}{m:>3}{zeta:>6.2f}{row['first_s']:>8.1f}{row['steady_s']:>9.2f}"
              f"{row['steps']:>7}{row['max_contact_force_N'] / 1e3:>9.1f}{row['mean_revolution_max_force_N'] / 1e3:>9.1f}"
              f"{row['impacts_per_revolution']:>8.1f}{row['slider_acc_peak']:>9.0f}"
              f"{row['slider_acc_rms']:>8.0f}{defl:>16}{row.get('moment_max_Nm', float('nan')):>8.1f}", flush=True)
    area, second = rod_section(mech)
    fitted = fit_through_the_link(mech) if args.fit else None
    implicit = implicit_against_explicit(mech, args.zeta) if args.implicit else None
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    atomic_write_json(args.json, {"rows": rows, "revolutions": args.revolutions, "measured": args.measured,
                                  "rod_area_m2": area,
                                  "rod_second_moment_m4": second, "rtol": 1e-6, "atol": 1e-9, "fit": fitted, "implicit": implicit,
                                  "date": time.strftime("%Y-%m-%d %H:%M"), "machine": platform.processor() or platform.machine(),
                                  "cpus": os.cpu_count(), "jaxclear": jc.__version__})
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
