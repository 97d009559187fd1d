"""docs/architecture.md's layer table against the imports (issue 40).

The table ("Layers and what each may import") gives each *unit* of jaxclear (a top-level
subpackage such as ``fitting/`` or a top-level module such as ``_storage.py``) its layer and what
it may import: ``-`` (no other unit), ``everything``, or ``layer A`` / ``layers A-B`` followed
by names in backquotes. A unit may import a unit of a layer below its own that the range
covers, and any unit that its column names (an import within the same layer is named there,
``sweep.lanes``); ``everything`` is not checked. Every import counts, at module level or in a
function (the check reads the source with ``ast``, as ``tests/test_boundaries.py`` does), and
every unit of jaxclear has its row."""

import ast
import importlib
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "jaxclear"
DOC = ROOT / "docs" / "architecture.md"


def units_on_disk() -> set[str]:
    """The top-level subpackages and modules of jaxclear (``fitting``, ``_storage``, ``__init__``)."""
    return {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()
            if (p.is_file() and p.suffix == ".py") or (p.is_dir() and (p / "__init__.py").is_file())}


def _unit_of_cell(name: str) -> str:
    return name.rstrip("/").removesuffix(".py").split("/")[0].split(".")[0]


def table() -> dict[str, tuple[int | None, str]]:
    """``unit -> (layer, may-import cell)`` from the doc's table (layer None for the ``-`` rows)."""
    text = DOC.read_text(encoding="utf-8")
    section = text.split("## Layers and what each may import", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        if not line.startswith("| ") or line.startswith("| layer") or line.startswith("|---"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        assert len(cells) == 4, f"a row of the layer table without four cells: {line[:80]}"
        layer = None if cells[0] == "-" else int(cells[0])
        for name in re.findall(r"`([^`]+)`", cells[1]):
            unit = _unit_of_cell(name)
            assert unit not in rows, f"{unit} has two rows in the layer table"
            rows[unit] = (layer, cells[3])
    return rows


def allowed(unit: str, rows: dict) -> set[str] | None:
    """The units ``unit`` may import (its own aside), or None: everything."""
    layer, cell = rows[unit]
    if cell.strip() == "everything":
        return None
    if cell.strip() == "-":
        return set()
    m = re.match(r"layers? (\d+)(?:-(\d+))?", cell)
    assert m, f"{unit}: the may-import cell {cell[:40]!r} names no layers"
    low, high = int(m.group(1)), int(m.group(2) or m.group(1))
    below = {u for u, (lay, _) in rows.items() if lay is not None and low <= lay <= high and lay < layer}
    named = {_unit_of_cell(n) for n in re.findall(r"`([^`]+)`", cell[m.end():])}
    assert named <= set(rows), f"{unit}: its may-import cell names {sorted(named - set(rows))}, not units"
    over = [n for n in named if rows[n][0] is None or rows[n][0] > layer]
    assert not over, f"{unit}: its may-import cell names {over}, above its own layer {layer}"
    return below | named


def _aliases() -> dict[str, str]:
    """``jaxclear.X`` module paths that are another module (a moved module's old path kept
    without warning, such as ``jaxclear.caches``): the path -> its home."""
    importlib.import_module("jaxclear")

    return {name: mod.__name__ for name, mod in list(sys.modules.items())
            if name.startswith("jaxclear.") and getattr(mod, "__name__", name) != name
            and isinstance(getattr(mod, "__name__", None), str) and mod.__name__.startswith("jaxclear")}


def imported_units(path: Path, units: set[str], aliases: dict[str, str], source: str | None = None) -> dict[str, int]:
    """The units the module at ``path`` (its text, or ``source`` in its place) imports, each with
    the line of its first import."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    is_init = parts[-1] == "__init__"
    module = parts[:-1] if is_init else parts
    found: dict[str, int] = {}

    def add(target: str, line: int):
        target = aliases.get(target, target)
        bits = target.split(".")
        if bits[0] != "jaxclear" or len(bits) < 2:
            return
        found.setdefault(bits[1] if bits[1] in units else "__init__", line)

    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8") if source is None else source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                add(alias.name, node.lineno)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module if is_init else module[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "jaxclear":  # from jaxclear import x / from .. import x: x is a unit (or the package's)
                for alias in node.names:
                    add(f"jaxclear.{alias.name}", node.lineno)
            else:
                add(target, node.lineno)
    return found


def test_every_unit_has_its_row_and_every_row_its_unit():
    rows, disk = table(), units_on_disk()
    assert not disk - set(rows), f"docs/architecture.md's layer table lacks {sorted(disk - set(rows))}"
    assert not set(rows) - disk, f"docs/architecture.md's layer table names {sorted(set(rows) - disk)}, not in jaxclear"


def test_no_unit_imports_what_its_row_does_not_allow():
    rows, disk = table(), units_on_disk()
    aliases = _aliases()
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        unit = rel.parts[0].removesuffix(".py") if len(rel.parts) == 1 else rel.parts[0]
        may = allowed(unit, rows)
        if may is None:
            continue
        for other, line in imported_units(path, disk, aliases).items():
            if other != unit and other not in may:
                bad.append(f"jaxclear/{rel.as_posix()}:{line}: {unit} (layer {rows[unit][0]}) imports {other} "
                           f"(layer {rows[other][0]}); its row allows {rows[unit][1][:60]!r}")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("cell, expected", [
    ("layer 0", {"a0", "b0"}),
    ("layers 0-1", {"a0", "b0", "c1"}),
    ("layer 0 (`a0`)", {"a0", "b0"}),
    ("layers 0-2 (`d2`: the same layer, named)", {"a0", "b0", "c1", "d2"}),
    ("layers 0-1 and `d2`", {"a0", "b0", "c1", "d2"}),
    ("-", set()),
])
def test_the_rule_reads_a_cell_as_documented(cell, expected):
    """A unit of layer 2: the layers below it in its range, and what its cell names."""
    rows = {"a0": (0, "-"), "b0": (0, "-"), "c1": (1, "layer 0"), "d2": (2, "layer 0"), "e2": (2, cell)}
    assert allowed("e2", rows) == expected


def test_the_check_catches_an_upward_import():
    """A model module that imported the integrator or the parameters would be reported."""
    source = "from ..integrate import simulate\nfrom .. import params\nimport jaxclear.fitting.run\n"
    got = imported_units(PACKAGE / "model" / "probe.py", units_on_disk(), {}, source)
    assert set(got) == {"integrate", "params", "fitting"}
    assert not set(got) & allowed("model", table())


#: Modules that ``import jaxclear`` leaves to their first use (issue 41, time to first result):
#: together they were about 1.3 s of a 3 s import on 2 cores (``python -X importtime``), the time
#: every command and every notebook pays before its first result.
LAZY = ("matplotlib", "scipy.stats", "scipy.interpolate", "scipy.optimize", "scipy.special")


def test_import_jaxclear_leaves_figures_and_statistics_to_their_first_use():
    import subprocess

    code = f"import sys, jaxclear; print([m for m in {LAZY!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).parent)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
