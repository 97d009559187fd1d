"""Boundaries between jaxclear's packages (issue 40, item 6).

A *package* here is a top-level subpackage (``jaxclear/fitting/``) or loose module
(``jaxclear/_storage.py``) of jaxclear. A module may use the private names (a leading underscore,
not a dunder) of its own package, and anything of jaxclear's top-level private modules
(``jaxclear/_errors.py``, ``_storage.py``, ``_types.py``, ...: the shared private base); it may
not import, or read as an attribute of an imported module, a private name or private module of
another package (``from ..plot import _helper``, ``from ..sweep._x import y``,
``params._accessor(...)``). What one package needs of another is public in its home module.
A package's ``__init__`` re-exports no private name."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "jaxclear"


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _module_name(path: Path) -> tuple[str, bool]:
    """``jaxclear.a.b`` of a file, and whether it is a package's ``__init__``."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    is_init = parts[-1] == "__init__"
    return ".".join(parts[:-1] if is_init else parts), is_init


def _owner(module: str) -> str:
    """The package a module belongs to: ``jaxclear.fitting.run`` -> ``fitting``; jaxclear itself -> ''."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _shared_base(module: str) -> bool:
    """A top-level private module of jaxclear (``jaxclear._storage``): anyone may use it."""
    parts = module.split(".")
    return len(parts) == 2 and parts[0] == "jaxclear" and _private(parts[1])


def _absolute(node: ast.ImportFrom, module: str, is_init: bool) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_init else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def violations(path: Path, source: str | None = None) -> list[str]:
    """What the module at ``path`` (its text, or ``source`` in its place) uses of another
    package's private names."""
    module, is_init = _module_name(path)
    own = _owner(module)
    tree = ast.parse(path.read_text(encoding="utf-8") if source is None else source)
    where = path.relative_to(ROOT).as_posix()
    found, bound = [], {}  # bound: local name -> the jaxclear module it names

    def foreign(target: str) -> bool:
        return target.split(".")[0] == "jaxclear" and not _shared_base(target) and (own == "" or _owner(target) != own)

    def check_module(target: str, line: int):
        if foreign(target) and any(_private(p) for p in target.split(".")[1:]):
            found.append(f"{where}:{line}: imports the private module {target}")

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                check_module(alias.name, node.lineno)
                if alias.asname:
                    bound[alias.asname] = alias.name
        elif isinstance(node, ast.ImportFrom):
            target = _absolute(node, module, is_init)
            check_module(target, node.lineno)
            for alias in node.names:
                full = f"{target}.{alias.name}"
                bound[alias.asname or alias.name] = full
                if _private(alias.name) and foreign(target) and not _shared_base(full):
                    found.append(f"{where}:{node.lineno}: imports the private name {alias.name} from {target}")
                if is_init and _private(alias.asname or alias.name) and target.startswith("jaxclear") \
                        and not _shared_base(full):
                    found.append(f"{where}:{node.lineno}: a package's __init__ re-exports the private name "
                                 f"{alias.asname or alias.name} (from {target})")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and _private(node.attr):
            target = bound.get(node.value.id)
            if target is not None and foreign(target) and not _shared_base(target):
                found.append(f"{where}:{node.lineno}: uses the private {node.attr} of {target}")
    return found


MODULES = sorted(PACKAGE.rglob("*.py"))


def test_no_module_uses_another_packages_private_names():
    bad = [v for path in MODULES for v in violations(path)]
    assert len(MODULES) > 100 and not bad, "\n".join(bad)


@pytest.mark.parametrize("source, rel, expected", [
    ("from ..plot import _helper\n", "jaxclear/designing/figures.py", "private name _helper from jaxclear.plot"),
    ("from . import params\nparams._accessor(m, n)\n", "jaxclear/derivatives.py", "private _accessor of jaxclear.params"),
    ("from .. import params\nparams._split(n)\n", "jaxclear/sweep/values.py", "private _split of jaxclear.params"),
    ("import jaxclear.sweep._x as x\n", "jaxclear/fitting/run.py", "private module jaxclear.sweep._x"),
    ("from ..sweep.batch import _runs\n", "jaxclear/fitting/run.py", "private name _runs from jaxclear.sweep.batch"),
    ("from .batch import _run_chunk\n", "jaxclear/sweep/__init__.py", "__init__ re-exports the private name _run_chunk"),
])
def test_the_check_catches_each_kind(source, rel, expected):
    """The check is not vacuous: each kind of crossing is reported, as a module of that package."""
    found = violations(ROOT / rel, source)
    assert any(expected in v for v in found), found


@pytest.mark.parametrize("source, rel", [
    ("from ._x import y\nfrom . import _z\n", "jaxclear/fitting/run.py"),       # its own package's private names
    ("from .._storage import _anything, json_text\n", "jaxclear/sweep/store.py"),  # the shared private base
    ("from . import _xla_flags\n", "jaxclear/__init__.py"),
    ("from ..sweep.batch import over_lanes\n", "jaxclear/fitting/sampler.py"),  # a public name of another package
])
def test_the_check_allows_own_and_shared_private_names(source, rel):
    assert violations(ROOT / rel, source) == []



def test_old_integrate_module_paths_warn_and_give_the_same_objects():
    """``jaxclear.integrate``'s modules are private; their old paths import for one release, each
    name read through them with a DeprecationWarning naming the public spelling."""
    import importlib
    import warnings

    import jaxclear as jc

    with pytest.warns(DeprecationWarning, match=r"jaxclear\.integrate\.settings\.MAX_OUT_SAMPLES is deprecated "
                                                r".*; use jaxclear\.integrate\.MAX_OUT_SAMPLES$"):
        from jaxclear.integrate.settings import MAX_OUT_SAMPLES
    assert MAX_OUT_SAMPLES == jc.integrate.MAX_OUT_SAMPLES
    with pytest.warns(DeprecationWarning, match="raise_for_status"):
        assert importlib.import_module("jaxclear.integrate.simulate").raise_for_status is jc.integrate.raise_for_status
    with pytest.warns(DeprecationWarning, match=r"integrate\.runs\.revolution_settings is deprecated"):
        assert jc.integrate.runs.revolution_settings is jc.integrate.revolution_settings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert jc.integrate.simulate is jc.simulate and jc.integrate.settings is jc.settings  # the functions


def test_moved_modules_keep_their_old_names_without_warning():
    """The loose modules that found a package are the same module objects under their old names."""
    import importlib
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        import jaxclear as jc
        for old, new in [("caches", "integrate.caches"), ("derivatives", "params.derivatives"),
                         ("presets", "mechanisms.presets"), ("mechanism_files", "mechanisms.files"),
                         ("profile_tables", "mechanisms.tables"), ("drawing", "plot.drawing"),
                         ("profile_figures", "plot.profiles")]:
            module = importlib.import_module(f"jaxclear.{new}")
            assert importlib.import_module(f"jaxclear.{old}") is module and getattr(jc, old) is module
        assert jc.params.replace is importlib.import_module("jaxclear.params.registry").replace
        assert jc.plot.plot_simulation is importlib.import_module("jaxclear.plot.figures").plot_simulation
        assert jc.io.write_json is importlib.import_module("jaxclear.io.timeseries").write_json
