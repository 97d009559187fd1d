"""The notebooks run end to end (with JAXCLEAR_QUICK=1: short simulations), in a scratch copy so
the committed notebooks and their figures are left as they are."""

import os
import shutil
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"


def execute_notebook(name: str, tmp_path: Path, timeout: int = 900):
    """Execute a scratch copy of notebook ``name`` in ``tmp_path`` with JAXCLEAR_QUICK=1, its
    figures to ``tmp_path/figures`` and its kernel's temporary folders (``tempfile.mkdtemp`` in
    the notebooks: their output folders) under ``tmp_path/tmp`` (TMPDIR), so that a run leaves
    nothing in the system's temporary folder beyond pytest's own, which pytest prunes."""
    src = NOTEBOOKS / name
    dst = tmp_path / name
    shutil.copy(src, dst)
    nb = nbformat.read(dst, as_version=4)
    env_before = {k: os.environ.get(k) for k in ("JAXCLEAR_QUICK", "JAXCLEAR_FIGURES", "MPLBACKEND", "TMPDIR")}
    (tmp_path / "tmp").mkdir(exist_ok=True)
    os.environ.update(JAXCLEAR_QUICK="1", JAXCLEAR_FIGURES=str(tmp_path / "figures"), MPLBACKEND="Agg",
                      TMPDIR=str(tmp_path / "tmp"))
    try:
        NotebookClient(nb, timeout=timeout, kernel_name="python3",
                       resources={"metadata": {"path": str(tmp_path)}}).execute()
    finally:
        for k, v in env_before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return nb


def run_notebook(name: str, tmp_path: Path, timeout: int = 900) -> tuple[list, str]:
    """Execute ``name`` (:func:`execute_notebook`), assert that no cell raised, and return the
    figures it wrote (sorted file names) and the text its cells printed."""
    nb = execute_notebook(name, tmp_path, timeout)
    cells = [c for c in nb.cells if c.cell_type == "code"]
    assert not [o for c in cells for o in c.outputs if o.output_type == "error"]
    figures = sorted(p.name for p in (tmp_path / "figures").glob("*.png"))
    return figures, "".join(o.get("text", "") for c in cells for o in c.outputs)


@pytest.mark.extended
def test_contact_models_notebook_runs(tmp_path):
    figures, text = run_notebook("contact_models.ipynb", tmp_path)
    assert figures == ["effective_restitution.png", "hybrid_vs_ln_orbits.png", "hybrid_vs_ln_signals.png"]
    # the single-impact check inside the notebook: simulated e equals the closed form
    lines = [line for line in text.splitlines() if "max |simulated - closed form|" in line]
    assert len(lines) == 8 and all(float(line.split("=")[-1]) < 1e-5 for line in lines)


@pytest.mark.skipif(not (NOTEBOOKS / "contact_models.ipynb").exists(), reason="notebook missing")
def test_committed_notebook_has_outputs_and_figures():
    nb = nbformat.read(NOTEBOOKS / "contact_models.ipynb", as_version=4)
    assert all(c.outputs for c in nb.cells if c.cell_type == "code")
    for fig in ("effective_restitution.png", "hybrid_vs_ln_orbits.png", "hybrid_vs_ln_signals.png"):
        assert (NOTEBOOKS / "figures" / fig).stat().st_size > 10_000


@pytest.mark.extended
def test_joints_notebook_runs(tmp_path):
    """notebooks/joints.ipynb (dry against lubricated benchmark, guide clearance) end to end, one
    crank revolution of each mechanism with JAXCLEAR_QUICK=1 (about 2 minutes on 2 shared cores,
    mostly compilation)."""
    figures, text = run_notebook("joints.ipynb", tmp_path)
    assert figures == ["joints_dry_vs_lubricated.png", "joints_guide_clearance.png"]
    assert "lubricated: impacts   0" in text


@pytest.mark.extended
def test_wear_notebook_runs(tmp_path):
    """notebooks/wear.ipynb at small settings (2 updates, 45 elements): runs, writes its two figures."""
    figures, text = run_notebook("wear.ipynb", tmp_path)
    assert figures == ["wear_profile.png", "wear_slider.png"]
    assert "largest wear depth" in text and "worn: peak |slider acceleration|" in text


@pytest.mark.extended
def test_design_notebook_runs(tmp_path):
    """notebooks/design.ipynb at small settings (the balanced four-bar, a 21 x 21 landscape, three
    iterations of a half-revolution design through impacts): runs, writes its two figures."""
    figures, text = run_notebook("design.ipynb", tmp_path)
    assert figures == ["design_comparison.png", "design_landscape.png"]
    assert "status converged" in text and "objective (RMS deviation" in text


@pytest.mark.slow
def test_uncertainty_notebook_runs(tmp_path):
    """notebooks/uncertainty.ipynb at small settings (0.6 ms record: the first impact, 2 chains x
    100 draws; 16 + 13 + 32 tolerance runs of a quarter revolution): runs, writes its three
    figures. Slow: about 4.5 minutes on 2 shared cores (10 with the 1.2 ms record it had), most
    of it compiling the fit's, the posterior's and the sweep's programs (the fit about 1 minute,
    NUTS through the sensitivities another)."""
    figures, text = run_notebook("uncertainty.ipynb", tmp_path, timeout=1800)
    assert figures == ["uncertainty_pair.png", "uncertainty_predictive.png", "uncertainty_tolerance.png"]
    assert "converged (" in text or "NOT CONVERGED" in text
    assert "P(peak > 66000 N)" in text


@pytest.mark.slow
def test_chaos_notebook_runs(tmp_path):
    """notebooks/chaos.ipynb at small settings (6 speeds, 6 revolutions; about 5 minutes on 2
    shared cores, mostly compiling the tangent program): runs, writes its two figures, prints the
    e-folding times."""
    figures, text = run_notebook("chaos.ipynb", tmp_path)
    assert figures == ["chaos_bifurcation.png", "chaos_points.png"]
    assert "lambda_1 =" in text and "0-1 test K =" in text and ("e-folding time" in text or "no horizon" in text)


@pytest.mark.extended
def test_flexible_links_notebook_runs(tmp_path):
    """notebooks/flexible_links.ipynb (issue 43: the benchmark slider-crank with its rod rigid,
    steel and ten times softer; one crank revolution each with JAXCLEAR_QUICK=1, 3 moduli): runs,
    writes its four figures, and the flexible rods bend while the rigid one has no deflection."""
    figures, text = run_notebook("flexible_links.ipynb", tmp_path)
    assert figures == ["flexible_drawing.png", "flexible_force_deflection.png", "flexible_shape.png", "flexible_sweep.png"]
    assert "midpoint deflection" in text and "20.7 GPa: largest deflection" in text


@pytest.mark.extended
def test_steady_operation_notebook_runs(tmp_path):
    """Shadowing derivatives (issue 44): on the forced pendulum the notebook's NILSS agrees with
    central differences of averages (measured 0.00 % and 0.04 % with the tangents read at fixed crank
    angle, 2026-12-03; 0.1 % and 0.2 % allowed, as tests/test_steady_shadowing.py: the central
    differences' own plateau is 1.5e-4 and 7e-6), and on the benchmark slider-crank it warns (not
    resolved)."""
    figures, text = run_notebook("steady_operation.ipynb", tmp_path)
    assert figures == ["steady_blocks.png", "steady_nilsas.png"]
    rows = {line.split()[0]: float(line.split()[-1].rstrip("%")) for line in text.splitlines()
            if line.startswith(("torsion_damping:hinge ", "speed_rpm "))}
    assert rows["torsion_damping:hinge"] < 0.1 and rows["speed_rpm"] < 0.2
    assert "warned: True" in text
    # Lorenz 63's three derivatives: NILSAS against NILSS within 4 combined standard errors (the
    # tests of both, tests/test_nilsas.py, ask the same)
    gaps = [float(line.split()[-3]) for line in text.splitlines() if line.startswith("d<z>/d")]
    assert len(gaps) == 3 and max(gaps) < 4.0, gaps
