"""Shared builders for tests. Importing jaxclear turns on float64."""

import atexit
import math
import os
import shutil
import sys
import tempfile
from pathlib import Path

# Hermetic caches: the compiled and traced programs that jaxclear keeps by default (jaxclear/integrate/caches.py)
# go to a temporary folder of this session, removed at its end, never the user's cache folder
# (nor a JAX cache the user configured: JAX_COMPILATION_CACHE_DIR is dropped). Child processes
# (the command line, tests/test_programs.py) inherit the folder. JAXCLEAR_CACHE_DIR=off in the
# environment runs the suite without caches.
# One folder for the whole run: pytest-xdist's workers are started by the controlling process after
# it has read this file, inherit its environment and find the folder it made (marked by
# JAXCLEAR_TEST_SESSION_CACHE), so a program traced and compiled by one worker is loaded by the
# other and by every notebook's kernel instead of being traced and compiled again. The process
# that made the folder removes it.
os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
SESSION_CACHE = None
if os.environ.get("JAXCLEAR_CACHE_DIR", "x").strip().lower() not in {"", "0", "off", "none", "false", "no"}:
    inherited = os.environ.get("JAXCLEAR_TEST_SESSION_CACHE")
    if inherited and inherited == os.environ.get("JAXCLEAR_CACHE_DIR") and os.path.isdir(inherited):
        SESSION_CACHE = inherited
    else:
        SESSION_CACHE = tempfile.mkdtemp(prefix="jaxclear-test-cache-")
        os.environ["JAXCLEAR_CACHE_DIR"] = os.environ["JAXCLEAR_TEST_SESSION_CACHE"] = SESSION_CACHE
        atexit.register(shutil.rmtree, SESSION_CACHE, ignore_errors=True)

import jax  # noqa: E402

import jaxclear as jc  # noqa: E402

if SESSION_CACHE is not None and jax.config.jax_compilation_cache_dir != SESSION_CACHE:  # a JAX cache set before jaxclear
    jc.enable_cache(SESSION_CACHE)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def free_journal(restitution=0.9, law="lankarani-nikravesh", speed=1.0, clearance=0.5e-3, mass=1.0,
                 friction=None, offset=(0.0, 0.0), stiffness=None, floor=1e-4, **law_options):
    """A free body whose centre is a journal inside a ground bearing at the origin; no gravity.
    It starts at ``offset`` moving along +x at ``speed`` m/s: one central impact."""
    body = jc.Body("pin", mass, 1e-3, {"c": (0.0, 0.0)}, position=(*offset, 0.0), velocity=(speed, 0.0, 0.0))
    joint = jc.ClearanceJoint(
        jc.GROUND, "hole", "pin", "c",
        bearing_radius=0.010, journal_radius=0.010 - clearance,
        law=jc.make_law(law, restitution=restitution, stiffness=stiffness, **law_options),
        friction=friction, impact_velocity_floor=floor,
        initial_offset=offset, initial_velocity=(speed, 0.0),
    )
    return jc.Mechanism([body], clearance_joints=[joint], gravity=(0.0, 0.0), ground_points={"hole": (0, 0)},
                        name="free-journal")


def clearance_pendulum(restitution=1.0, friction=0.0, length=0.2, mass=1.0, clearance=0.5e-3):
    """A bar hanging from a ground bearing through a clearance joint at its top end (no ideal
    joints, no drivers): a free mechanism with 3 degrees of freedom. Starts tilted 30 degrees,
    journal centred, at rest."""
    th = math.radians(30)
    # centroid below the pivot along the bar; bar axis from top end (journal) to centroid
    cx, cy = 0.5 * length * math.sin(th), -0.5 * length * math.cos(th)
    phi = th - math.pi / 2  # body x axis points from the journal towards the free end
    body = jc.Body("bar", mass, mass * length**2 / 12, {"top": (-length / 2, 0.0)}, position=(cx, cy, phi))
    joint = jc.ClearanceJoint(
        jc.GROUND, "pivot", "bar", "top", bearing_radius=0.010, journal_radius=0.010 - clearance,
        law=jc.make_law("lankarani-nikravesh", restitution=restitution),
        friction=jc.Friction(friction),
    )
    return jc.Mechanism([body], clearance_joints=[joint], ground_points={"pivot": (0, 0)}, name="pendulum")


from bench_steady_averages import slider_crank_exact  # noqa: E402,F401  (benchmarks/: the closed form, one place)


def _refuse_constant(name):
    raise ValueError(f"{name} is not JSON (a strict parser refuses it; write null)")


def strict_json(text: str):
    """``text`` parsed as strict JSON: the bare ``NaN``, ``Infinity`` and ``-Infinity`` that
    Python's json module writes and reads by default are errors, as in every other parser."""
    import json

    return json.loads(text, parse_constant=_refuse_constant)


def assert_strict_json(folder) -> list[str]:
    """Every ``*.json`` file under ``folder`` parses as strict JSON (:func:`strict_json`), and every
    line of every ``*.jsonl`` file; returns the names checked (relative to ``folder``)."""
    folder = Path(folder)
    checked, bad = [], []
    for path in sorted([*folder.rglob("*.json"), *folder.rglob("*.jsonl")]):
        text = path.read_text(encoding="utf-8")
        pieces = [line for line in text.splitlines() if line.strip()] if path.suffix == ".jsonl" else [text]
        for piece in pieces:
            try:
                strict_json(piece)
            except ValueError as err:
                bad.append(f"{path.relative_to(folder)}: {err}")
                break
        checked.append(str(path.relative_to(folder)))
    assert not bad, "files that are not strict JSON:\n" + "\n".join(bad)
    return checked
