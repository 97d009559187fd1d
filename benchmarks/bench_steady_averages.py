"""Long-time averages of the benchmark slider-crank's steady chaotic running, and their slopes
against the clearance, the restitution and the crank speed: the truth a shadowing derivative of
that mechanism must meet (issue 44), and whether the averages are differentiable at all.

For each parameter, ``--values`` values in a band round the preset's (clearance 0.45-0.55 mm,
restitution 0.85-0.95, crank speed 4750-5250 rpm), each run as ``--members`` independent motions
(start crank angles spread over the circle), each ``--transient`` revolutions left out and then
``--revolutions`` revolutions averaged (100 samples a revolution). Objectives, time averages over
the steady running:

* ``rms_dev``: the RMS of the slider's acceleration minus the ideal joint's (closed form of the
  ideal slider-crank, x = r cos phi + sqrt(l^2 - r^2 sin^2 phi), phi = angle0 + omega t) [m/s^2];
* ``rms_acc``: the RMS of the slider's acceleration [m/s^2];
* ``onsets``: contact onsets per revolution (a count: a rate that can jump);
* ``peak_force``: the mean over revolutions of each revolution's largest sampled normal force in
  the clearance joint [N] (the samples of the run's grid: the peak of an impact lasting a few
  samples is read where a sample falls, as ``jc.steady_derivatives(statistic="revolution_peak")``
  reads it on its own grid).

Each member's steady part is cut into blocks of ``--block`` revolutions; the value's average is
the mean of its blocks, its standard error the blocks' spread over sqrt(blocks) (the motion
forgets its start in a few milliseconds, 1/lambda_1 = 2.3 ms, so blocks of 50 revolutions
(0.6 s) are independent). The slope: weighted least squares of the averages against the value,
a straight line and a parabola; the line's slope with its 95 % interval, the parabola's slope at
the preset's value, and the lack-of-fit statistic chi^2 / dof of the line with its p-value: a
p-value below 0.01 says the average is not a straight line over the band (curved, or not smooth:
see the residuals).

``python benchmarks/bench_steady_averages.py [--parameters clearance,restitution,speed_rpm]
[--values 10] [--members 4] [--revolutions 500] [--json PATH]`` prints a table and writes the
JSON after every parameter (a killed run resumes with the parameters done; the output is locked
while it runs).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import jaxclear as jc  # noqa: I001  (float64 first)
import jax
import numpy as np
from scipy import stats

from jaxclear._storage import atomic_write_json, locked_folder

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_JSON = os.path.join(HERE, "results", "steady_averages.json")
PRESET = "flores-slider-crank"
#: The bands swept round the preset's values (relative half-width of the band).
BANDS = {"clearance": 0.1, "restitution": None, "speed_rpm": 0.05}
RESTITUTION_BAND = (0.85, 0.95)
SAMPLES = 100  # per revolution
#: The objectives averaged (the module docstring says what each is).
OBJECTIVES = ("rms_dev", "rms_acc", "onsets", "peak_force")
CRANK, ROD = 0.05, 0.12  # the preset's crank radius and rod length [m] (Flores et al. 2004)


def slider_crank_exact(phi, omega, r=CRANK, l=ROD, xp=np):
    """Exact slider position [m], velocity [m/s] and acceleration [m/s^2] of the ideal
    slider-crank at crank angle ``phi`` and constant speed ``omega`` (closed form of
    x = r cos phi + sqrt(l^2 - r^2 sin^2 phi) and its derivatives; the tests' truth too,
    tests/conftest.py). ``xp``: the array module (``jax.numpy`` inside a traced objective,
    benchmarks/bench_shadowing.py)."""
    s, c = xp.sin(phi), xp.cos(phi)
    root = xp.sqrt(l**2 - r**2 * s**2)
    x = r * c + root
    dx = -r * s - r**2 * s * c / root
    ddx = -r * c - r**2 * (c**2 - s**2) / root - r**4 * s**2 * c**2 / root**3
    return x, dx * omega, ddx * omega**2


def member_blocks(mech, angle0: float, transient: int, revolutions: int, block: int) -> dict:
    """Block averages ``{objective: (revolutions // block,)}`` of one motion from crank angle
    ``angle0`` [rad]."""
    m = jc.params.replace(mech, "angle0", angle0)
    omega = float(jc.params.get(m, "speed"))
    period = 2 * math.pi / abs(omega)
    total = transient + revolutions
    s = jc.settings(total * period, n_out=total * SAMPLES + 1, max_steps=20_000_000)
    sol = jc.simulate(m, s)
    jax.block_until_ready(sol.q)
    if int(sol.status) != 0:
        raise RuntimeError(f"run failed: status {int(sol.status)} ({jc.STATUS.get(int(sol.status), '?')})")
    t = np.asarray(sol.ts)
    acc = np.asarray(sol.coordinate(m, "slider", "x", 2))
    dev = acc - slider_crank_exact(angle0 + omega * t, omega)[2]
    onsets = np.asarray(sol.memory.impacts)[:, 0]
    force = np.asarray(sol.normal_force)[:, 0]
    out = {key: [] for key in OBJECTIVES}
    first = transient * SAMPLES
    for b in range(revolutions // block):
        a, z = first + b * block * SAMPLES, first + (b + 1) * block * SAMPLES
        out["rms_dev"].append(math.sqrt(float(np.mean(dev[a:z] ** 2))))
        out["rms_acc"].append(math.sqrt(float(np.mean(acc[a:z] ** 2))))
        out["onsets"].append(float(onsets[z] - onsets[a]) / block)
        out["peak_force"].append(float(np.mean(np.max(force[a:z].reshape(block, SAMPLES), axis=1))))
    return {k: np.asarray(v) for k, v in out.items()}


#: Members whose averages differ more than their own errors allow (chi^2 of the member means about
#: their weighted mean, p below this) have settled on different attractors: the value is
#: multistable, its average depends on the start, and it is left out of ``fits_single``.
AGREE_P = 1e-3


def members_agree(means, ses) -> float:
    """p-value of the member averages ``means`` (standard errors ``ses``) being one average:
    chi^2 of their weighted scatter with ``len(means) - 1`` degrees of freedom (1.0 for one member)."""
    m, se = np.asarray(means, dtype=float), np.asarray(ses, dtype=float)
    if m.size < 2:
        return 1.0
    w = 1.0 / np.maximum(se, 1e-300) ** 2
    mean = np.sum(w * m) / np.sum(w)
    return float(stats.chi2.sf(np.sum(w * (m - mean) ** 2), m.size - 1))


def regression(x: np.ndarray, y: np.ndarray, se: np.ndarray, x0: float) -> dict:
    """Weighted least squares of ``y`` (standard errors ``se``) against ``x``: the line's slope
    with its standard error and 95 % interval, chi^2/dof and p-value of the line's lack of fit,
    and the parabola's slope at ``x0`` with its standard error; ``line`` and ``parabola``: their
    coefficients in powers of ``x - x0`` (constant first), which the figure draws."""
    w = 1.0 / se**2
    out = {}
    for deg in (1, 2):
        X = np.vander(x - x0, deg + 1, increasing=True)
        cov = np.linalg.inv(X.T @ (w[:, None] * X))
        beta = cov @ (X.T @ (w * y))
        chi2 = float(np.sum(w * (y - X @ beta) ** 2))
        dof = len(x) - deg - 1
        out[deg] = (beta, cov, chi2, dof)
    beta, cov, chi2, dof = out[1]
    t95 = stats.t.ppf(0.975, dof)
    slope_se = math.sqrt(cov[1, 1])
    b2, c2, chi2_2, dof2 = out[2]
    return {"slope": float(beta[1]), "slope_se": slope_se,
            "slope_95": [float(beta[1] - t95 * slope_se), float(beta[1] + t95 * slope_se)],
            "line_chi2_per_dof": chi2 / dof, "line_p": float(stats.chi2.sf(chi2, dof)),
            "parabola_slope": float(b2[1]), "parabola_slope_se": math.sqrt(c2[1, 1]),
            "parabola_chi2_per_dof": chi2_2 / dof2, "parabola_p": float(stats.chi2.sf(chi2_2, dof2)),
            "line": [float(b) for b in beta], "parabola": [float(b) for b in b2]}


def values_of(name: str, mech, n: int, band: tuple | None = None) -> tuple[np.ndarray, float]:
    """The band of ``n`` values of ``name`` round the preset's (or ``band = (low, high)``) and
    the preset's value."""
    x0 = float(jc.params.get(mech, name))
    if band is not None:
        return np.linspace(*band, n), x0
    if name == "restitution":
        return np.linspace(*RESTITUTION_BAND, n), x0
    return x0 * np.linspace(1 - BANDS[name], 1 + BANDS[name], n), x0


def study(name: str, n: int, members: int, transient: int, revolutions: int, block: int,
          band: tuple | None = None) -> dict:
    mech = jc.preset(PRESET)
    xs, x0 = values_of(name, mech, n, band)
    angles = np.linspace(0.0, 2 * math.pi, members, endpoint=False)
    t0 = time.perf_counter()
    rows = []
    for x in xs:
        m = jc.params.replace(mech, name, float(x))
        blocks = [member_blocks(m, float(a), transient, revolutions, block) for a in angles]
        row = {"value": float(x)}
        for key in blocks[0]:
            allb = np.concatenate([b[key] for b in blocks])
            row[key] = float(np.mean(allb))
            row[key + "_se"] = float(np.std(allb, ddof=1) / math.sqrt(allb.size))
            row[key + "_members"] = [float(np.mean(b[key])) for b in blocks]
            row[key + "_members_se"] = [float(np.std(b[key], ddof=1) / math.sqrt(b[key].size)) for b in blocks]
        row["members_agree_p"] = members_agree(row["rms_dev_members"], row["rms_dev_members_se"])
        rows.append(row)
        print(f"  {name} = {x:.6g}: " + ", ".join(f"{k} {row[k]:.6g} +- {row[k + '_se']:.2g}"
                                                  for k in blocks[0]), flush=True)
    def fits_of(kept):
        return {key: regression(np.array([r["value"] for r in kept]), np.array([r[key] for r in kept]),
                                np.array([r[key + "_se"] for r in kept]), x0)
                for key in OBJECTIVES if key in kept[0]}

    single = [r for r in rows if r["members_agree_p"] >= AGREE_P]
    return {"parameter": name, "preset_value": x0, "values": n, "members": members, "transient": transient,
            "revolutions": revolutions, "block": block, "rows": rows, "fits": fits_of(rows),
            "multistable": [r["value"] for r in rows if r["members_agree_p"] < AGREE_P],
            "fits_single": fits_of(single) if len(single) >= 4 else None,
            "wall_s": time.perf_counter() - t0, "revolutions_run": n * members * (transient + revolutions)}


def plot(studies: list, path: str) -> str:
    """Each study's averages (error bars: 2 standard errors; grey dots: each motion's; red: a
    multistable value) against its parameter, with the weighted line and parabola of the values
    on one attractor, one row per parameter, one column per objective; saved to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = tuple(k for k in OBJECTIVES if k in studies[0]["rows"][0])
    labels = {"rms_dev": "RMS slider acc. deviation [m/s$^2$]", "rms_acc": "RMS slider acc. [m/s$^2$]",
              "onsets": "contact onsets per revolution", "peak_force": "mean peak contact force [N]"}
    fig, axes = plt.subplots(len(studies), len(keys), figsize=(4 * len(keys), 3.2 * len(studies)), squeeze=False)
    for row, s in zip(axes, studies):
        x = np.array([r["value"] for r in s["rows"]])
        for ax, key in zip(row, keys):
            y = np.array([r[key] for r in s["rows"]])
            se = np.array([r[key + "_se"] for r in s["rows"]])
            ok = np.array([r.get("members_agree_p", 1.0) >= AGREE_P for r in s["rows"]])
            for r in s["rows"]:
                ax.plot([r["value"]] * len(r[key + "_members"]), r[key + "_members"], ".", color="0.75", ms=3)
            ax.errorbar(x[ok], y[ok], yerr=2 * se[ok], fmt="o", ms=3, capsize=2, color="k", label="average +- 2 SE")
            if not ok.all():
                ax.errorbar(x[~ok], y[~ok], yerr=2 * se[~ok], fmt="s", ms=4, capsize=2, color="tab:red",
                            label="multistable (motions differ)")
            f = regression(x[ok], y[ok], se[ok], s["preset_value"])  # the values on one attractor
            xx = np.linspace(x.min(), x.max(), 100)
            for curve, style in (("line", "-"), ("parabola", "--")):
                ax.plot(xx, np.polynomial.polynomial.polyval(xx - s["preset_value"], f[curve]), style, lw=1,
                        label=curve)
            ax.set_title(f"slope {f['slope']:.3g}, line p = {f['line_p']:.2g}"
                         + (" (one attractor)" if s.get("multistable") else ""), fontsize=9)
            ax.set_xlabel(s["parameter"])
            ax.set_ylabel(labels[key], fontsize=8)
            ax.axvline(s["preset_value"], color="0.7", lw=0.8)
        row[0].legend(fontsize=7)
    fig.suptitle(f"{PRESET}: long-time averages of steady running ({studies[0]['members']} motions x "
                 f"{studies[0]['revolutions']} revolutions a value)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--parameters", default="clearance,restitution,speed_rpm")
    p.add_argument("--values", type=int, default=10)
    p.add_argument("--members", type=int, default=4)
    p.add_argument("--transient", type=int, default=20)
    p.add_argument("--revolutions", type=int, default=500)
    p.add_argument("--block", type=int, default=50)
    p.add_argument("--band", action="append", default=[], metavar="NAME=LOW,HIGH",
                   help="the band of one parameter instead of the default (a closer look; use another --json)")
    p.add_argument("--json", default=DEFAULT_JSON)
    a = p.parse_args(argv)
    bands = {}
    for item in a.band:
        name, _, lh = item.partition("=")
        try:
            bands[name] = tuple(float(v) for v in lh.split(","))
        except ValueError:
            bands[name] = ()
        if name not in BANDS or len(bands[name]) != 2 or not bands[name][0] < bands[name][1]:
            p.error(f"--band {item!r}: expected NAME=LOW,HIGH with LOW < HIGH, NAME one of {sorted(BANDS)}")
    if a.revolutions % a.block or a.values < 4 or a.members < 1:
        p.error("--revolutions must be a multiple of --block; --values >= 4; --members >= 1")
    path = os.path.abspath(a.json)
    with locked_folder(os.path.dirname(path)):
        done = {}
        if os.path.exists(path):
            with open(path, encoding="utf-8") as f:
                saved = json.load(f)
            same = {k: saved["meta"].get(k) for k in ("values", "members", "transient", "revolutions", "block",
                                                      "objectives")}
            if same == {"values": a.values, "members": a.members, "transient": a.transient,
                        "revolutions": a.revolutions, "block": a.block, "objectives": list(OBJECTIVES)} and \
                    {k: tuple(v) for k, v in saved["meta"].get("bands", {}).items()} == bands:
                done = {s["parameter"]: s for s in saved["studies"]}
        meta = {"date": time.strftime("%Y-%m-%d"), "preset": PRESET, "values": a.values, "members": a.members,
                "transient": a.transient, "revolutions": a.revolutions, "block": a.block, "samples": SAMPLES,
                "cpus": os.cpu_count(), "bands": bands, "objectives": list(OBJECTIVES),
                "command": "python benchmarks/bench_steady_averages.py" + "".join(f" --band {b}" for b in a.band)}
        for name in a.parameters.split(","):
            if name not in BANDS:
                p.error(f"--parameters: {name!r}; valid: {sorted(BANDS)}")
            if name not in done:
                print(f"{name}: {a.values} values x {a.members} members x {a.revolutions} revolutions", flush=True)
                done[name] = study(name, a.values, a.members, a.transient, a.revolutions, a.block, bands.get(name))
                atomic_write_json(path, {"meta": meta, "studies": list(done.values())})
        if done:
            print("figure:", plot(list(done.values()), os.path.splitext(path)[0] + ".png"))
        print(f"\n{'parameter':12s} {'objective':9s} {'slope (line)':>14s} {'95 % interval':>30s} "
              f"{'chi2/dof':>9s} {'p':>8s} {'slope (parabola)':>18s}")
        for name, s in done.items():
            for label, fits in (("", s["fits"]), (" (one attractor)", s.get("fits_single") if s.get("multistable") else None)):
                for key, f in (fits or {}).items():
                    print(f"{name:12s} {key + label:9s} {f['slope']:14.5g} [{f['slope_95'][0]:13.5g}, "
                          f"{f['slope_95'][1]:13.5g}] {f['line_chi2_per_dof']:9.2f} {f['line_p']:8.2g} "
                          f"{f['parabola_slope']:11.5g} +- {f['parabola_slope_se']:.2g}")
            if s.get("multistable"):
                print(f"{name:12s} multistable (the motions settle on different attractors) at "
                      f"{', '.join(f'{v:.6g}' for v in s['multistable'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
