"""The libraries whose internals jaxclear leans on are at the versions it is tested with."""

import re

import pytest

from jaxclear.integrate import _versions as versions


def test_installed_versions_are_tested_ones():
    versions.check()  # raises RuntimeError naming every untested version


def test_pyproject_bounds_match_the_table():
    import pathlib

    text = (pathlib.Path(__file__).parents[1] / "pyproject.toml").read_text()
    for name, (low, high) in versions.TESTED.items():
        found = re.search(rf'"{name}>=([0-9.]+),<([0-9.]+)"', text)
        assert found, f"pyproject.toml has no bounded requirement for {name}"
        assert versions._key(found.group(1)) == versions._key(low) and found.group(2) == high, name


def test_untested_version_fails_with_a_clear_message(monkeypatch):
    monkeypatch.setattr(versions, "version", lambda name: "0.9.1" if name == "diffrax" else "0.10.2")
    monkeypatch.setattr(versions, "TESTED", {"diffrax": ("0.7.0", "0.8")})
    with pytest.raises(RuntimeError, match=r"diffrax 0.9.1 \(tested: >=0.7.0,<0.8\).*diffrax internals"):
        versions.check()
