"""The mechanism-files tutorial runs end to end with small settings (JAXCLEAR_QUICK=1), its fit
section through jc.fit on the rocker channel (the notebook asserts the recovered values)."""

import pytest

from test_notebooks import execute_notebook


@pytest.mark.extended
def test_mechanism_files_tutorial_runs(tmp_path):
    nb = execute_notebook("mechanism_files.ipynb", tmp_path)
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors
    figures = sorted(p.name for p in (tmp_path / "figures").glob("*"))
    assert figures == ["tutorial_fit.png", "tutorial_four_bar.gif", "tutorial_four_bar_check.png",
                       "tutorial_pendulum.gif", "tutorial_pendulum_channels.png", "tutorial_pendulum_check.png"]
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs)
    assert "K / K_true = " in text
