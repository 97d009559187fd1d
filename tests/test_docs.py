"""The documentation: every notebook's markdown math renders (matplotlib's mathtext, an
independent TeX-subset parser) and holds no control character; the repository refers to no file
outside itself; the MkDocs site builds in strict mode (every page, every API page, every
notebook, no broken link)."""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
MATH = re.compile(r"\$\$(.+?)\$\$|\$(.+?)\$", flags=re.S)
#: Control characters that a JSON escape such as "\f" (for "\frac") or "\b" leaves in a string.
CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f]")


def _markdown_cells(path: Path):
    nb = json.loads(path.read_text(encoding="utf-8"))
    for i, cell in enumerate(nb["cells"]):
        if cell["cell_type"] == "markdown":
            yield i, "".join(cell["source"])


def _math(path: Path):
    for i, text in _markdown_cells(path):
        for m in MATH.finditer(text):
            yield i, m.group(1) or m.group(2)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_markdown_has_no_control_characters(path):
    bad = [(i, repr(m.group()), text[max(0, m.start() - 30): m.end() + 30])
           for i, text in _markdown_cells(path) for m in CONTROL.finditer(text)]
    assert not bad, f"{path.name}: control characters in markdown cells (cell, char, context): {bad}"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_math_renders(path):
    """Every $...$ and $$...$$ of the markdown cells goes through matplotlib's mathtext parser;
    a form feed where ``\\frac`` belongs (``\\x0crac``) fails here."""
    from matplotlib.mathtext import MathTextParser

    parser = MathTextParser("agg")
    failures = []
    for i, expr in _math(path):
        if CONTROL.search(expr):
            failures.append((i, expr, "control character"))
            continue
        try:
            parser.parse(f"${expr}$", dpi=72)
        except ValueError as err:
            failures.append((i, expr, str(err).splitlines()[-1] if str(err) else "parse error"))
    assert not failures, f"{path.name}: math that does not render (cell, expression, error): {failures}"


def test_math_check_catches_a_form_feed():
    """The check above is not vacuous: the old defect (a form feed for ``\\f`` of ``\\frac``)
    is caught, and the repaired formula renders."""
    from matplotlib.mathtext import MathTextParser

    parser = MathTextParser("agg")
    broken = json.loads('"K = \\frac{4}{3}"')  # JSON reads \f as a form feed
    assert CONTROL.search(broken)
    with pytest.raises(ValueError):
        parser.parse(f"${broken}$", dpi=72)
    parser.parse("$K = \\frac{4}{3(\\sigma_i+\\sigma_j)}\\sqrt{R_BR_J/(R_B-R_J)}$", dpi=72)


#: Phrases that point at files or notes outside the repository.
OUTSIDE = re.compile(r"\.\./shared|shared/(spec|seed)|spec/model|model-next|spec[ -]section|seed paper", re.I)
#: Files still being moved by another change (jaxclear/fit.py -> jaxclear/fitting/).
_PENDING: set[str] = set()


def test_repository_refers_to_no_file_outside_it():
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=False).stdout.split()
    if not files:
        pytest.skip("not a git checkout")
    hits = []
    for name in files:
        if name in _PENDING or name == "tests/test_docs.py" or not name.endswith((".py", ".md", ".ipynb", ".toml", ".yml")):
            continue
        text = (ROOT / name).read_text(encoding="utf-8", errors="replace")
        for lineno, line in enumerate(text.splitlines(), 1):
            if OUTSIDE.search(line):
                hits.append(f"{name}:{lineno}: {line.strip()[:100]}")
    assert not hits, "references to files outside the repository:\n" + "\n".join(hits)


def test_site_builds_strict(tmp_path):
    """``mkdocs build --strict`` of the whole site (theory pages, API pages from the docstrings,
    the executed notebooks, every internal link and anchor) into a scratch folder; about 10 s."""
    import os

    env = dict(os.environ, PYTHONPATH=str(ROOT), NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
                           "-d", str(tmp_path / "site")], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-4000:]
    site = tmp_path / "site"
    for page in ("index.html", "theory/hybrid/index.html", "theory/contact-laws/index.html",
                 "api/contact/index.html", "notebooks/contact_models/index.html", "architecture/index.html"):
        assert (site / page).is_file(), page
    api = (site / "api/contact/index.html").read_text(encoding="utf-8")
    assert "arithmatex" in api and ":math:" not in api  # docstring math reaches MathJax
    hybrid = (site / "theory/hybrid/index.html").read_text(encoding="utf-8")
    assert "Dynamic analysis of mechanical systems with planar revolute joints with clearance" in hybrid


def test_griffe_extension_converts_rst_math_and_roles():
    sys.path.insert(0, str(ROOT / "docs"))
    try:
        from griffe_rst import rst_to_markdown
    finally:
        sys.path.pop(0)
    text = "Force :math:`F = K\\delta` (see :func:`~jaxclear.contact.hertz.chi_flores`, ``x``).\n\n.. math:: a = b\n          + c\n\nAfter."
    out = rst_to_markdown(text)
    assert "$F = K\\delta$" in out and "`jaxclear.contact.hertz.chi_flores`" in out and "`x`" in out
    assert "$$\na = b\n+ c\n$$" in out and out.rstrip().endswith("After.")
