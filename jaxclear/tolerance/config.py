r"""A tolerance study's TOML file (``jaxclear tolerance STUDY.toml``; :func:`load_study`)::

    [mechanism]              # preset = "flores-slider-crank" (default) and preset options, or file = "..."
    preset = "flores-slider-crank"

    [parameters]             # the distributions (jaxclear.tolerance.distributions)
    clearance = {distribution = "normal", mean = 0.5e-3, sd = 0.0167e-3, low = 1e-5}
    "point_x:crank.A" = {distribution = "uniform", low = 0.0499, high = 0.0501}

    [correlations]           # optional
    pairs = [["clearance", "point_x:crank.A", 0.2]]

    [study]                  # n, method ("sobol" | "mc"), seed, metrics, linearise, derivatives, sobol_n, importance_n
    n = 256
    sobol_n = 64

    [limits]                 # metric = limit: probability of exceeding it
    peak_contact_force_n = 7.0e4

    [run]                    # each batch's sweep settings (jaxclear.sweep.SweepConfig)
    revolutions = 1.0

    [settings]               # how every run is integrated (jaxclear.Settings by name; optional)
    rtol = 1e-7
    derivative_tolerance = 0.5

    [output]
    dir = "tolerance-out"

Every key is checked before anything runs; an unknown one is an error naming the allowed ones.
"""

from __future__ import annotations

import os

from .._errors import ParameterError
from .._storage import read_toml
from .distributions import inputs_from_dict
from ..integrate import OPTION_KEYS
from .study import RUN_OPTIONS

TABLES = {"mechanism": None, "parameters": None, "correlations": ("pairs",),
          "study": ("n", "method", "seed", "metrics", "linearise", "derivatives", "sobol_n", "importance_n"), "limits": None,
          "run": RUN_OPTIONS, "settings": OPTION_KEYS, "output": ("dir", "progress")}


def study_from_dict(doc: dict, source: str = "<dict>", settings_options: dict | None = None) -> dict:
    """Keyword arguments of :func:`~.study.tolerance_study` from the file's tables; the
    ``[settings]`` table (and the deprecated ``solver``, ``rtol``, ``atol``, ``max_steps`` of
    ``[run]``) with ``settings_options`` (the command line's) over it become ``settings``, read
    as a sweep file's (:func:`jaxclear.sweep.config.settings_table`)."""
    from ..sweep.config import settings_table

    bad = sorted(set(doc) - set(TABLES))
    if bad:
        raise ParameterError(f"{source}: unknown table(s) {bad}; allowed: {list(TABLES)}")
    for table, keys in TABLES.items():
        got = doc.get(table, {})
        if not isinstance(got, dict):
            raise ParameterError(f"{source}: '{table}' must be a table ([{table}])")
        if keys is not None and set(got) - set(keys):
            raise ParameterError(f"{source}: unknown key(s) {sorted(set(got) - set(keys))} in [{table}]; allowed: "
                                 f"{list(keys)}")
    run = dict(doc.get("run", {}))
    settings = settings_table(doc, run, source, settings_options)
    kwargs = {"inputs": inputs_from_dict(doc, source), **doc.get("study", {}), **run}
    if settings is not None:
        kwargs["settings"] = settings
    if "metrics" in kwargs:
        kwargs["metrics"] = tuple(kwargs["metrics"])
    kwargs["limits"] = dict(doc.get("limits", {}))
    mech = dict(doc.get("mechanism", {}))
    if "file" in mech:
        from ..mechanisms.files import load_mechanism

        if set(mech) != {"file"}:
            raise ParameterError(f"{source}: [mechanism] with 'file' takes no other key (got {sorted(mech)})")
        folder = os.path.dirname(source) if os.path.isfile(source) else ""
        kwargs["mech"] = load_mechanism(os.path.join(folder, str(mech["file"])))
    elif set(mech) - {"preset"}:
        from ..mechanisms.presets import preset

        kwargs["mech"] = preset(mech.pop("preset", "flores-slider-crank"), **mech)
    elif "preset" in mech:
        kwargs["preset"] = mech["preset"]
    out = doc.get("output", {})
    kwargs["out"] = out.get("dir", "tolerance-out")
    if "progress" in out:
        kwargs["progress"] = bool(out["progress"])
    return kwargs


def load_study(path: str, settings_options: dict | None = None) -> dict:
    """:func:`study_from_dict` of a TOML file (a syntax error names the file and line)."""
    return study_from_dict(read_toml(path, "tolerance study file"), path, settings_options)
