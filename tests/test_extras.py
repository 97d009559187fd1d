"""Optional extras (jaxclear._extras): a feature whose extra is missing says so in one line, with
the ``pip install`` line, before any work; the table of extras is pyproject.toml's."""

from __future__ import annotations

import pathlib
import re
import sys
import tomllib

import numpy as np
import pytest

import jaxclear as jc
from jaxclear import _extras
from jaxclear.cli import main

ROOT = pathlib.Path(__file__).parents[1]


def test_extras_table_matches_pyproject():
    """Every extra of the table is an optional-dependency group of pyproject.toml and names
    each of its modules' distributions there (module and distribution names agree, case aside)."""
    groups = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    for extra, modules in _extras.EXTRAS.items():
        assert extra in groups, extra
        names = {re.split(r"[<>=!;\[ ]", req, maxsplit=1)[0].lower() for req in groups[extra]}
        for module in modules:
            assert module.lower() in names, (extra, module)


def _forbid(monkeypatch, *modules):
    """The modules cannot be imported (``sys.modules[name] = None``, as an uninstalled package)."""
    for name in modules:
        monkeypatch.setitem(sys.modules, name, None)


def test_require_extra_names_the_module_and_the_install_line(monkeypatch):
    _forbid(monkeypatch, "SALib")
    assert _extras.missing_modules("uncertainty") == ["SALib"]
    with pytest.raises(jc.MissingExtraError) as info:
        _extras.require_extra("uncertainty", "the Sobol' indices")
    text = str(info.value)
    assert text == ("the Sobol' indices needs SALib, of the optional extra [uncertainty], which is not installed: "
                    'pip install "jaxclear[uncertainty]"')
    assert isinstance(info.value, ImportError) and isinstance(info.value, jc.JaxclearError)
    assert info.value.name == "SALib"


_STUDY = """\
[mechanism]
preset = "flores-slider-crank"
[parameters]
clearance = {distribution = "uniform", low = 0.45e-3, high = 0.55e-3}
[study]
n = 4
sobol_n = 4
[run]
revolutions = 0.1
samples_per_revolution = 100
"""


def test_cli_tolerance_without_salib_says_which_extra_before_any_run(tmp_path, capsys, monkeypatch):
    """``jaxclear tolerance`` with sobol_n > 0 and no SALib: exit 2, one line with the extra and
    the pip line, and no simulation started (run_sweep is never called)."""
    import jaxclear.sweep

    _forbid(monkeypatch, "SALib")
    ran = []
    monkeypatch.setattr(jaxclear.sweep, "run_sweep", lambda *a, **k: ran.append(1))
    path = tmp_path / "study.toml"
    path.write_text(_STUDY)
    code = main(["tolerance", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "SALib" in err[0] and err[0].endswith('pip install "jaxclear[uncertainty]"'), err
    assert ran == [] and not (tmp_path / "o" / "runs").exists()


def test_cli_fit_posterior_without_blackjax_says_which_extra_before_the_fit(tmp_path, capsys, monkeypatch):
    import jaxclear.cli.fit as cli_fit

    _forbid(monkeypatch, "blackjax")
    monkeypatch.setattr(cli_fit, "fit", lambda *a, **k: pytest.fail("the fit ran"))
    path = tmp_path / "rec.csv"
    path.write_text("t,slider_acc_m_s2\n" + "".join(f"{i * 5e-6},{0.0}\n" for i in range(200)))
    code = main(["fit", str(path), "--posterior", "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0] == ('error: jaxclear fit --posterior needs blackjax, of the optional extra [uncertainty], which is '
                      'not installed: pip install "jaxclear[uncertainty]"')


def test_rosenstein_without_nolds_says_which_extra(monkeypatch):
    from jaxclear.chaos.signals import rosenstein

    _forbid(monkeypatch, "nolds")
    with pytest.raises(jc.MissingExtraError, match=r'rosenstein needs nolds.*pip install "jaxclear\[chaos\]"$'):
        rosenstein(np.sin(np.arange(200) * 0.3), 1e-3)
