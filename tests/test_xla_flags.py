"""jaxclear's XLA:CPU options for single-kernel loops (``jaxclear/_xla_flags.py``): how it is
added to ``XLA_FLAGS``, its switch, the warning where JAX started first, and that it changes
speed, not results (a run with and without it, in separate processes, agrees to rounding)."""

import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

import jaxclear as jc
from jaxclear import _xla_flags as X

OPT = f"{X.OPTION}={X.DEFAULT_BYTES}"
YNN = X.NO_LIBRARY_FUSIONS


@pytest.mark.parametrize("before, after", [
    ("", f"--xla_backend_extra_options={OPT} {YNN}"),
    ("--xla_force_host_platform_device_count=2",
     f"--xla_force_host_platform_device_count=2 --xla_backend_extra_options={OPT} {YNN}"),
    ("--xla_backend_extra_options=xla_cpu_disable_loop_unrolling=false",
     f"--xla_backend_extra_options=xla_cpu_disable_loop_unrolling=false,{OPT} {YNN}"),
    ("--xla_backend_extra_options=", f"--xla_backend_extra_options={OPT} {YNN}"),
    (f"--xla_backend_extra_options={X.OPTION}=5", f"--xla_backend_extra_options={X.OPTION}=5"),  # the user's
    ("--xla_cpu_experimental_ynn_fusion_type=dot",  # the user's YNNPACK choice is kept
     f"--xla_cpu_experimental_ynn_fusion_type=dot --xla_backend_extra_options={OPT}"),
])
def test_option_is_added_to_the_flags(before, after):
    assert X.with_loop_option(before, X.DEFAULT_BYTES) == after


@pytest.mark.parametrize("raw, value", [("", X.DEFAULT_BYTES), ("0", 0), ("65536", 65536), ("1e6", 1000000)])
def test_requested_bytes(monkeypatch, raw, value):
    monkeypatch.setenv(X.ENV, raw)
    assert X.requested_bytes() == value


@pytest.mark.parametrize("raw", ["-1", "many", "1.5", "nan"])
def test_bad_limit_names_the_variable_and_the_range(monkeypatch, raw):
    monkeypatch.setenv(X.ENV, raw)
    with pytest.raises(jc.ParameterError, match=f"{X.ENV}.*>= 0"):
        X.requested_bytes()


def test_started_backends_are_left_alone_with_a_warning(monkeypatch):
    monkeypatch.setenv("XLA_FLAGS", "--xla_force_host_platform_device_count=1")
    monkeypatch.delenv(X.ENV, raising=False)
    with pytest.warns(X.SlowLoopsWarning, match="Import jaxclear before"):
        assert X.apply(started=True) is False
    assert os.environ["XLA_FLAGS"] == "--xla_force_host_platform_device_count=1"
    monkeypatch.setenv(X.ENV, "0")  # switched off: silent, unchanged
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert X.apply(started=True) is False
        assert X.apply(started=False) is False
    assert os.environ["XLA_FLAGS"] == "--xla_force_host_platform_device_count=1"


def test_this_process_runs_with_the_option():
    """The test suite imports jaxclear before any JAX computation (conftest.py), so it runs
    what users run."""
    assert X.loop_kernels_active()


_CHILD = r"""
import json, os, sys
import jaxclear as jc, numpy as np
from conftest import free_journal
sol = jc.simulate(free_journal(restitution=0.8, friction=jc.Friction(0.1), offset=(-0.2e-3, 0.25e-3)),
                  jc.settings(1.0e-3, n_out=5, rtol=1e-8, atol=1e-12))
print(json.dumps({"flags": os.environ.get("XLA_FLAGS", ""), "q": np.asarray(sol.q).tolist(),
                  "fn": float(np.max(sol.normal_force)), "steps": int(sol.num_steps)}))
"""


def _child(env_extra):
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", X.ENV)}
    env.update(env_extra, JAXCLEAR_CACHE_DIR="off", PYTHONPATH=os.pathsep.join(sys.path))
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True, timeout=300,
                         cwd=os.path.dirname(__file__))
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.extended
def test_same_results_with_and_without_single_kernel_loops():
    """An oblique impact with friction (rtol 1e-8) in a fresh process with the option and one
    without: same step count, positions and peak contact force to 1e-9 relative (the two
    programs round differently; at rtol 1e-8 that moves the solution by far less than the
    tolerance, and here the step sequences are equal)."""
    on, off = _child({}), _child({X.ENV: "0"})
    assert X.OPTION in on["flags"] and X.OPTION not in off["flags"]
    assert X.NO_LIBRARY_FUSIONS in on["flags"] and X.NO_LIBRARY_FUSIONS not in off["flags"]
    assert on["steps"] == off["steps"]
    np.testing.assert_allclose(on["q"], off["q"], rtol=1e-9, atol=1e-15)
    assert on["fn"] == pytest.approx(off["fn"], rel=1e-9)


def test_host_devices_request(monkeypatch):
    """``request_host_devices`` adds XLA's host-device count to ``XLA_FLAGS``, except where the
    user named one, where fewer than two are asked for, or where JAX has started."""
    monkeypatch.setenv("XLA_FLAGS", "--xla_backend_extra_options=a=1")
    assert X.request_host_devices(3, started=False) is True
    assert os.environ["XLA_FLAGS"] == "--xla_backend_extra_options=a=1 --xla_force_host_platform_device_count=3"
    assert X.request_host_devices(5, started=False) is False  # a count is there: kept
    assert os.environ["XLA_FLAGS"].endswith("count=3")
    monkeypatch.setenv("XLA_FLAGS", "")
    assert X.request_host_devices(1, started=False) is False
    assert X.request_host_devices(4, started=True) is False
    assert os.environ["XLA_FLAGS"] == ""
    assert X.usable_cpus() >= 1


_FRESH = r"""
import jaxclear as jc
from jax._src import xla_bridge
from jaxclear import _xla_flags as X
started = xla_bridge.backends_are_initialized()
asked = X.request_host_devices(3)
mech = jc.preset("flores-slider-crank")
import jax
print(started, asked, jax.device_count())
"""


def test_import_starts_no_jax_backend():
    """``import jaxclear`` creates no JAX array (module constants such as ``STEEL`` hold NumPy
    scalars), so options set after the import still reach XLA: a fresh process asks for three
    host devices after importing jaxclear and gets them."""
    env = dict(os.environ)
    env.pop("XLA_FLAGS", None)
    done = subprocess.run([sys.executable, "-c", _FRESH], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-3:] == ["False", "True", "3"]


def test_sweep_command_asks_for_one_device_per_core(monkeypatch, tmp_path):
    """``jaxclear sweep`` asks for one host device per usable core before anything else (here
    recorded: this test process's backends run already)."""
    from jaxclear.cli import main
    from jaxclear.cli import sweep as cli_sweep

    asked = []
    monkeypatch.setattr(cli_sweep, "request_host_devices", lambda n=None: asked.append(n) or False)
    assert main(["sweep", str(tmp_path / "missing.toml")]) != 0
    assert asked == [None]  # the default: one per usable core


def test_sensitivities_loop_compiles_to_single_kernels():
    """The error-controlled sensitivities (``jax.jacfwd`` of a run, two parameters) batch the
    vector field's products over the tangents; with YNNPACK's custom fusions off
    (``X.NO_LIBRARY_FUSIONS``) no product becomes one, and every ``while`` loop of the program
    is hoisted into a single kernel (``xla_cpu_small_call``). Measured with the fusions on: the
    loops stay thunks and a 4-parameter Jacobian of the clearance-guide slider-crank takes 6x
    as long (jaxclear/_xla_flags.py)."""
    import jax
    import jax.numpy as jnp
    from conftest import free_journal

    from jaxclear import params

    assert X.NO_LIBRARY_FUSIONS in os.environ.get("XLA_FLAGS", "")
    mech = free_journal(restitution=0.8, friction=jc.Friction(0.1), offset=(-0.2e-3, 0.25e-3))
    s = jc.settings(0.5e-3, n_out=5)

    def run(x):
        m = params.replace_many(mech, {"stiffness": x[0], "restitution": x[1]})
        return jc.simulate(m, s).q[-1]

    x = jnp.asarray([float(params.get(mech, "stiffness")), 0.8])
    text = jax.jit(jax.jacfwd(run)).lower(x).compile().as_text()
    assert "__ynn_fusion" not in text
    assert text.count(" while(") > 0
    assert text.count("xla_cpu_small_call") >= text.count(" while(")
