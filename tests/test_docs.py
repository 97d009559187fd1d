"""The documentation: every notebook's markdown math renders (matplotlib's mathtext, an
independent TeX-subset parser) and holds no control character; the repository refers to no file
outside itself; the MkDocs site builds in strict mode (every page, every API page, every
notebook, no broken link); every Python source compiles without a warning."""

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


def test_sources_compile_without_warnings():
    """Every Python file compiles with no warning: an invalid escape such as "\\d" in a
    non-raw docstring's math is a DeprecationWarning today and a SyntaxWarning from Python 3.12
    (an error later); it also reaches the API pages unescaped only by luck."""
    import warnings

    files = sorted(p for d in ("jaxclear", "tests", "benchmarks") for p in (ROOT / d).rglob("*.py"))
    bad = []
    for path in files:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            compile(path.read_text(encoding="utf-8"), str(path), "exec")
        bad += [f"{path.relative_to(ROOT)}:{w.lineno}: {w.message}" for w in caught]
    assert len(files) > 100 and not bad, "\n".join(bad)


def test_site_builds_strict(tmp_path):
    """``mkdocs build --strict`` of the whole site (theory pages, API pages from the docstrings,
    the executed notebooks, every internal link and anchor) into a scratch folder; about 10 s.
    Every name of ``jaxclear.__all__`` is documented in it."""
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
    check_site_is_offline(site)
    check_reference_documents_all(site)


#: What a page may load from elsewhere: nothing. Script sources, module imports, style sheets.
_EXTERNAL = re.compile(r"""<script[^>]*\ssrc=["']?(?:https?:)?//|import\(\s*["'](?:https?:)?//|"""
                       r"""<link[^>]*rel=["']?stylesheet[^>]*href=["']?(?:https?:)?//|"""
                       r"""<link[^>]*href=["']?(?:https?:)?//[^>]*rel=["']?stylesheet""", re.I)


def check_site_is_offline(site: Path):
    """The built site references no external script or style sheet (formulas rendered by the
    MathJax it ships, docs/hooks.py), and every script it loads is one of its files."""
    pages = list(site.rglob("*.html"))
    external = [f"{p.relative_to(site)}: {m.group(0)[:80]}" for p in pages
                for m in _EXTERNAL.finditer(p.read_text(encoding="utf-8"))]
    assert not external, external
    for page in pages:
        for src in re.findall(r"<script[^>]*\ssrc=\"([^\"]*)\"", page.read_text(encoding="utf-8")):
            target = site / src.lstrip("/") if src.startswith("/") else page.parent / src
            assert src and target.is_file(), f"{page.relative_to(site)} loads {src!r}, not a file of the site"
    assert (site / "javascripts/mathjax/es5/tex-mml-chtml.js").stat().st_size > 500_000
    assert (site / "javascripts/mathjax/LICENSE").is_file()
    assert list((site / "javascripts/mathjax/es5/output/chtml/fonts").rglob("*.woff")), "MathJax's fonts"


def test_offline_check_catches_external_scripts(tmp_path):
    """The check above is not vacuous: a CDN script, a module import from a CDN and a Google
    Fonts style sheet are each caught."""
    for bad in ('<script src="https://cdn.jsdelivr.net/npm/mathjax@3/es5/tex-mml-chtml.js"></script>',
                '<script type="module">await import("https://cdnjs.cloudflare.com/x.mjs")</script>',
                '<link rel="stylesheet" href="https://fonts.googleapis.com/css?family=Roboto">'):
        assert _EXTERNAL.search(bad), bad


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


# ---- statements that go stale: each list in the docs is checked against the code ---------------

def _read(rel: str) -> str:
    return (ROOT / rel).read_text(encoding="utf-8")


def _nav_pages(node) -> list[str]:
    """Every page path in mkdocs.yml's nav."""
    if isinstance(node, str):
        return [node]
    if isinstance(node, dict):
        return [p for v in node.values() for p in _nav_pages(v)]
    return [p for v in node for p in _nav_pages(v)]


def test_docs_index_links_every_notebook_and_page():
    """docs/index.md's map of the site names every notebook (it listed 3 of 6) and every page of
    the navigation except the API pages, which the API index lists; the nav holds every notebook."""
    import yaml

    nav = _nav_pages(yaml.safe_load(_read("mkdocs.yml").replace("!!python", "#"))["nav"])
    index = _read("docs/index.md")
    notebooks = [f"notebooks/{p.name}" for p in NOTEBOOKS]
    assert sorted(p for p in nav if p.startswith("notebooks/")) == sorted(notebooks)
    missing = [p for p in nav if p != "index.md" and not p.startswith("api/") and f"({p}" not in index]
    assert not missing, f"docs/index.md does not link {missing}"


def _api_index_exports() -> list[str]:
    """The names in the "exports" column of docs/api/index.md's table, row after row."""
    rows = [line for line in _read("docs/api/index.md").splitlines() if line.startswith("| [") or
            line.startswith("| this page |")]
    return [n for row in rows for n in re.findall(r"`([A-Za-z_][A-Za-z_0-9]*)`", row.split(" | ")[2])]


def test_all_is_the_public_api_and_the_api_index_lists_exactly_it():
    """``jaxclear.__all__`` holds every public name jaxclear binds (modules aside) and nothing
    else; the API index's exports column lists exactly it, each name once (it omitted the three
    joints, wear and synthetic_record once, and jaxclear had no ``__all__``)."""
    import types

    import jaxclear as jc

    public = {n for n in dir(jc) if not n.startswith("_") and not isinstance(getattr(jc, n), types.ModuleType)}
    assert len(jc.__all__) == len(set(jc.__all__)) and set(jc.__all__) == public
    listed = _api_index_exports()
    twice = sorted({n for n in listed if listed.count(n) > 1})
    assert not twice, f"docs/api/index.md lists {twice} more than once"
    assert not set(jc.__all__) - set(listed), f"docs/api/index.md does not list {sorted(set(jc.__all__) - set(listed))}"
    assert not set(listed) - set(jc.__all__), f"docs/api/index.md lists {sorted(set(listed) - set(jc.__all__))}, " \
                                              "not in jaxclear.__all__"


def _resolve(path: str) -> list:
    """The objects a dotted path of the API reference names (``jaxclear.model.bodies.GROUND``), read
    both ways: the longest importable module and attributes after it (``jaxclear.chaos.lyapunov.
    lyapunov_map``: the package's attribute ``lyapunov`` is the function), and as Python reads an
    expression, attribute by attribute, a submodule where there is no such attribute
    (``jaxclear.integrate.simulate`` is the function, not the old module path of that name)."""
    import importlib

    found = []
    parts = path.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for part in parts[i:]:
                obj = getattr(obj, part)
            found.append(obj)
        except AttributeError:
            pass
        break
    obj = importlib.import_module(parts[0])
    for i, part in enumerate(parts[1:], 2):
        if hasattr(obj, part):
            obj = getattr(obj, part)
            continue
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            return found
    return found + [obj]


def check_reference_documents_all(site: Path):
    """Every name of ``jaxclear.__all__`` has its entry in the built API reference: a heading whose
    anchor names the same object (``poincare_section`` is ``jaxclear.analysis.sections.section``)."""
    import jaxclear as jc

    anchors = {a for page in (site / "api").rglob("*.html")
               for a in re.findall(r'id="(jaxclear\.[A-Za-z_0-9.]+)"', page.read_text(encoding="utf-8"))}
    by_last = {}
    for a in anchors:
        by_last.setdefault(a.rsplit(".", 1)[1], []).append(a)
    missing = []
    for name in jc.__all__:
        obj = getattr(jc, name)
        candidates = by_last.get(name, []) + by_last.get(getattr(obj, "__name__", name), [])
        if not any(o is obj for a in candidates for o in _resolve(a)):
            missing.append(name)
    assert not missing, f"the API reference does not document {missing}"


def test_mechanism_file_friction_table_lists_every_friction_law():
    """The friction table of docs/mechanism-files.md has a row per law a mechanism file accepts
    (it listed 4 of 10), and names each law's own keys."""
    from jaxclear.contact.friction import FRICTION_MODELS

    text = _read("docs/mechanism-files.md")
    table = text[text.index("### `friction`"):].split("\n## ")[0]
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| `([a-z-]+)` \| (.*) \|$", table, flags=re.M)}
    rows.pop("model")  # the header
    assert sorted(rows) == sorted(FRICTION_MODELS)
    for name, (_, keys) in FRICTION_MODELS.items():
        assert all(f"`{k}`" in rows[name] for k in keys), (name, keys, rows[name])


def test_docs_name_every_force_element():
    """The clearance-joint page's "force elements" paragraph and the other-joints page name every
    force element jaxclear exports (the first called the revolute joint the only one)."""
    import inspect

    import jaxclear as jc

    elements = [n for n in dir(jc) if inspect.isclass(getattr(jc, n)) and issubclass(getattr(jc, n),
                jc.AbstractForceElement) and not inspect.isabstract(getattr(jc, n)) and not n.startswith("Abstract")]
    assert len(elements) == 4, elements
    general = _read("docs/theory/clearance-joint.md").split("## Force elements in general")[1].split("\n## ")[0]
    others = _read("docs/theory/other-joints.md")
    assert all(f"`{n}`" in general for n in elements), (elements, general)
    assert all(f"`{n}`" in others for n in elements if n != "ClearanceJoint"), elements
    assert "today" not in general


def test_fit_docs_and_help_say_what_the_fit_does():
    """The fit's theory page says whether its model runs with exact onsets as the code does (it
    said without), and `fit --help` names the library each optimizer comes from (it called the
    Levenberg-Marquardt an optax transformation)."""
    import optimistix as optx

    from jaxclear.cli import build_parser
    from jaxclear.fitting.problem import FIT_ONSETS
    from jaxclear.fitting.solver import make_optimizer
    from jaxclear.integrate import ExactOnsets

    page = " ".join(_read("docs/theory/fit.md").split())
    exact = isinstance(FIT_ONSETS, ExactOnsets)
    assert ("integrates with exact contact onsets" in page) == exact
    assert ("without exact contact onsets" in page) != exact
    fit = next(a for a in build_parser()._subparsers._group_actions[0].choices["fit"]._actions
               if "--optimizer" in a.option_strings)
    assert isinstance(make_optimizer("levenberg-marquardt").solver, optx.LevenbergMarquardt)
    assert isinstance(make_optimizer("adam").solver, optx.OptaxMinimiser)
    assert "levenberg-marquardt (optimistix's LevenbergMarquardt" in fit.help and "optax's adam" in fit.help


def test_license_and_citation_agree_with_pyproject():
    """LICENSE is the MIT licence that pyproject.toml declares (an SPDX expression and the licence
    file, PEP 639: setuptools refuses the older TOML-table form from 2027-02-18); CITATION.cff
    (Citation File Format 1.2.0, validated once with cffconvert) names the package's version and
    licence."""
    import tomllib

    import yaml

    project = tomllib.loads(_read("pyproject.toml"))["project"]
    assert project["license"] == "MIT" and project["license-files"] == ["LICENSE"]
    assert _read("LICENSE").startswith("MIT License\n") and "Permission is hereby granted, free of charge" in _read("LICENSE")
    cff = yaml.safe_load(_read("CITATION.cff"))
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software" and cff["authors"]
    assert cff["version"] == project["version"] and cff["license"] == "MIT"
    assert cff["title"].startswith("jaxclear")


def test_readme_quick_start_is_what_ci_runs():
    """The README's quick start is two commands: one installs and runs the main job on a built-in
    default (``jaxclear simulate`` without arguments), one installs the test extras and runs the
    tests; .ci/run runs that test command verbatim. The README stays a front page."""
    readme = _read("README.md")
    block = readme.split("## Quick start", 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    run, test = block.strip().splitlines()
    assert run == "python3 -m pip install -e . && jaxclear simulate"
    assert test.startswith("python3 -m pip install -e \".[test]\" && python3 -m pytest")
    assert test in _read(".ci/run").splitlines()
    assert len(readme.splitlines()) <= 200
    # the derivatives' section replaced the placeholder: it says what they are and links the theory
    assert "Derivatives/sensitivities" not in readme
    assert "## Derivatives" in readme and "docs/theory/sensitivities.md" in readme


def test_reference_mechanisms_page_lists_every_preset():
    """docs/theory/presets.md has a row per preset (it had 3 of 5)."""
    import jaxclear as jc

    page = _read("docs/theory/presets.md")
    assert sorted(re.findall(r"^\| `([a-z0-9-]+)` \|", page, flags=re.M)) == sorted(jc.preset_names())
