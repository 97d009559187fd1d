"""Every driver takes one Settings (issue 40, item 2): ``settings=`` reaches its runs whole, the
driver replacing only what it owns; the old keywords work for one release with a
DeprecationWarning and give the same settings; both at once is a ParameterError naming both;
the command line's one option group reads its defaults from Settings and goes through the same
conversion as the files' ``[settings]`` tables.

Fast: nothing here compiles a run but the sweep-against-simulate check and the statistics fit's
step-limited run."""

from __future__ import annotations

import dataclasses
import inspect
import warnings

import numpy as np
import pytest

import jaxclear as jc
from jaxclear import ParameterError
from jaxclear.cli import build_parser
from jaxclear.cli.settings import FLAGS, given_options, settings_from_args
from jaxclear.fitting import problem as fit_problem
from jaxclear.integrate._settings import OPTION_KEYS, default_settings, option_values, settings_from_options
from jaxclear.sweep import SweepConfig, config_from_dict, make_plan
from jaxclear.sweep.batch import run_settings

GRID = {"clearance": [0.5e-3]}
MECH = jc.preset("flores-slider-crank")


class Stop(Exception):
    """Raised by a stand-in to end a driver once it has shown what it would run."""


def _cfg(**kw):
    return SweepConfig(grid=dict(GRID), ideal_reference=False, progress=False, revolutions=0.1,
                       samples_per_revolution=40, **kw)


# --------------------------------------------------------------------------------------
# the one conversion of names
# --------------------------------------------------------------------------------------

def test_settings_from_options_names_every_strategy_and_checks_keys():
    s = settings_from_options({"solver": "bosh3", "rtol": 1e-7, "derivative_tolerance": 0.5, "output": "block",
                               "onsets": "step", "max_steps": 1000})
    assert s.solver == jc.SOLVERS["bosh3"]() and s.rtol == 1e-7 and s.max_steps == 1000
    assert s.derivatives == jc.Sensitivity(0.5) and s.output == jc.SampleBlock() and s.onsets == jc.StepOnsets()
    assert settings_from_options({"derivatives": "forward"}).derivatives == jc.ThroughLoop("forward")
    assert option_values(s)["onsets"] == "step" and option_values(s)["derivative_tolerance"] == 0.5
    assert settings_from_options({}) == default_settings()
    with pytest.raises(ParameterError, match=r"f.toml: \[settings\]: unknown key\(s\) \['rtl'\]; allowed"):
        settings_from_options({"rtl": 1e-7}, source="f.toml: [settings]")
    with pytest.raises(ParameterError, match=r"rtol = 'tight': expected a number"):
        settings_from_options({"rtol": "tight"})
    with pytest.raises(ParameterError, match=r"onsets = 'maybe'"):
        settings_from_options({"onsets": "maybe"})


# --------------------------------------------------------------------------------------
# sweep
# --------------------------------------------------------------------------------------

def test_sweep_runs_use_the_whole_settings_replacing_only_what_the_sweep_owns():
    given = jc.settings(7.0, t_start=1.0, n_out=9, rtol=1e-9, atol=1e-12, max_steps=12_345, progress=True,
                        derivatives=jc.Sensitivity(0.5), onsets=jc.StepOnsets(), output=jc.SampleBlock(),
                        solver="dopri5")
    cfg = _cfg(settings=given)
    s = run_settings(make_plan(cfg, None), cfg.base_mechanism)
    assert (s.rtol, s.atol, s.max_steps, s.solver) == (1e-9, 1e-12, 12_345, jc.SOLVERS["dopri5"]())
    # the derivative tolerance reaches the sweep's runs (and so a derivative of them: the tolerance study's)
    assert s.derivatives == jc.Sensitivity(0.5) and s.onsets == jc.StepOnsets() and s.output == jc.SampleBlock()
    # what the sweep owns: the span of 0.1 revolution from 0, its samples, no raise, no bar
    assert float(s.t_end) == pytest.approx(0.1 * float(jc.crank_period(MECH)), rel=1e-14)
    assert (s.t_start, s.n_out, s.throw, s.progress) == (0.0, cfg.n_out, False, False)
    # without settings: Settings' defaults with the sweep's step limit
    d = _cfg().run_settings
    assert d == dataclasses.replace(default_settings(), max_steps=jc.sweep.config.MAX_STEPS)
    # equal settings, equal plans (one compilation); another rtol, another plan
    assert make_plan(_cfg(settings=given), None) == make_plan(cfg, None)
    assert make_plan(_cfg(settings=dataclasses.replace(given, rtol=1e-8)), None) != make_plan(cfg, None)


def test_sweep_hash_of_default_settings_is_unchanged_and_new_fields_enter_it():
    old_style = _cfg().describe()["run"]
    assert {k: old_style[k] for k in ("solver", "rtol", "atol", "max_steps")} == {
        "solver": "tsit5", "rtol": 1e-6, "atol": 1e-9, "max_steps": 200_000}
    assert "settings" not in old_style
    changed = _cfg(settings=jc.settings(1.0, max_steps=200_000, derivative_tolerance=0.5)).describe()["run"]
    assert changed["settings"] == {"derivative_tolerance": 0.5}
    assert _cfg().sweep_hash() != _cfg(settings=jc.settings(1.0, max_steps=200_000, onsets="step")).sweep_hash()


def test_sweep_old_keywords_warn_and_give_the_same_settings_and_hash():
    with pytest.warns(DeprecationWarning, match=r"SweepConfig\(solver=, rtol=.*settings=jc.settings"):
        old = _cfg(solver="bosh3", rtol=1e-7)
    new = _cfg(settings=jc.settings(1.0, solver="bosh3", rtol=1e-7, max_steps=200_000))
    assert old.run_settings == new.run_settings and old.sweep_hash() == new.sweep_hash()
    with pytest.raises(ParameterError, match=r"both settings= and rtol= given"):
        _cfg(settings=jc.settings(1.0), rtol=1e-7)


def test_sweep_file_settings_table_and_the_command_line_over_it():
    doc = {"grid": dict(GRID), "run": {"revolutions": 0.1, "samples_per_revolution": 40, "ideal_reference": False},
           "settings": {"rtol": 1e-7, "derivative_tolerance": 0.5, "onsets": "step"}}
    s = config_from_dict(doc, source="s.toml").run_settings
    assert (s.rtol, s.derivatives, s.onsets, s.max_steps) == (1e-7, jc.Sensitivity(0.5), jc.StepOnsets(), 200_000)
    s = config_from_dict(doc, source="s.toml", settings_options={"rtol": 1e-9}).run_settings
    assert (s.rtol, s.derivatives) == (1e-9, jc.Sensitivity(0.5))
    old = {**doc, "run": {**doc["run"], "solver": "bosh3", "atol": 1e-12}, "settings": {}}
    with pytest.warns(DeprecationWarning, match=r"s.toml: writing \['atol', 'solver'\] in \[run\] is deprecated.*; use a \[settings\] table"):
        s_old = config_from_dict(old, source="s.toml").run_settings
    s_new = config_from_dict({**old, "run": doc["run"], "settings": {"solver": "bosh3", "atol": 1e-12}},
                             source="s.toml").run_settings
    assert s_old == s_new
    both = {**doc, "run": {**doc["run"], "rtol": 1e-8}}
    with pytest.raises(ParameterError, match=r"\['rtol'\] given both in \[run\] and in \[settings\]"):
        config_from_dict(both, source="s.toml")
    with pytest.raises(ParameterError, match=r"s.toml: \[settings\]: unknown key\(s\) \['rtl'\]"):
        config_from_dict({**doc, "settings": {"rtl": 1.0}}, source="s.toml")


@pytest.mark.extended
def test_a_tight_rtol_given_to_a_sweep_gives_the_tight_run():
    """One run of a sweep with ``settings=jc.settings(..., rtol=1e-9)``: its step counts are
    those of ``jc.simulate`` at rtol 1e-9 over the same span, not those at the default 1e-6."""
    tight = jc.settings(1.0, rtol=1e-9, atol=1e-12, solver="bosh3")
    cfg = _cfg(settings=tight)
    plan = make_plan(cfg, None)
    from jaxclear.sweep.batch import run_outputs
    import jax.numpy as jnp

    out = run_outputs(plan, cfg.base_mechanism, None, jnp.asarray([0.5e-3]))
    mech = jc.params.replace(MECH, "clearance", 0.5e-3)
    span = dict(n_out=cfg.n_out, max_steps=200_000, solver="bosh3")
    ref = jc.simulate(mech, jc.settings(0.1 * float(jc.crank_period(mech)), rtol=1e-9, atol=1e-12, **span))
    loose = jc.simulate(mech, jc.settings(0.1 * float(jc.crank_period(mech)), **span))
    assert int(out["num_steps"]) == int(ref.num_steps) != int(loose.num_steps)
    assert int(out["num_rejected_steps"]) == int(ref.num_rejected_steps)


# --------------------------------------------------------------------------------------
# tolerance study
# --------------------------------------------------------------------------------------

INPUTS = {"parameters": {"clearance": {"distribution": "uniform", "low": 0.45e-3, "high": 0.55e-3}}}


def _study_configs(monkeypatch, **kw):
    """The sweep configurations a tolerance study would run (stopped at its first batch)."""
    from jaxclear import sweep
    from jaxclear.tolerance import inputs_from_dict

    seen = []

    def run_sweep(cfg, restart=False):
        seen.append(cfg)
        raise Stop

    monkeypatch.setattr(sweep, "run_sweep", run_sweep)
    with pytest.raises(Stop):
        jc.tolerance_study(inputs_from_dict(INPUTS), n=2, method="mc", out="unused", progress=False,
                           revolutions=0.1, samples_per_revolution=40, **kw)
    return seen


def test_tolerance_study_takes_settings_and_its_old_keywords_warn(monkeypatch):
    given = jc.settings(1.0, rtol=1e-7, derivatives=jc.Sensitivity(0.5))
    (cfg,) = _study_configs(monkeypatch, settings=given)
    assert cfg.run_settings.rtol == 1e-7 and cfg.run_settings.derivatives == jc.Sensitivity(0.5)
    with pytest.warns(DeprecationWarning, match=r"tolerance_study\(solver=, rtol=.*settings=jc.settings"):
        (old,) = _study_configs(monkeypatch, rtol=1e-7, solver="bosh3")
    (new,) = _study_configs(monkeypatch, settings=jc.settings(1.0, rtol=1e-7, solver="bosh3", max_steps=200_000))
    assert old.run_settings == new.run_settings
    with pytest.raises(ParameterError, match=r"tolerance_study: both settings= and rtol= given"):
        _study_configs(monkeypatch, settings=given, rtol=1e-7)


def test_tolerance_study_derivative_run_uses_the_derivative_tolerance(monkeypatch):
    """The estimate from derivatives differentiates one run of the study's sweep: its settings
    carry the given ``Sensitivity(tolerance)``."""
    import jax.numpy as jnp

    from jaxclear.sweep import batch
    from jaxclear.tolerance import study

    plans = []

    def run_outputs(plan, mech, ideal, row):
        plans.append(run_settings(plan, mech))
        return {"peak_contact_force_n": jnp.sum(row)}

    monkeypatch.setattr(batch, "run_outputs", run_outputs)
    run = dict(revolutions=0.1, samples_per_revolution=40, settings=jc.settings(1.0, derivative_tolerance=0.25))
    grads = study._derivative_gradients(MECH, None, run, ("peak_contact_force_n",), ["clearance"],
                                        np.asarray([0.5e-3]), "unused")
    assert grads["peak_contact_force_n"].tolist() == [1.0]
    assert plans[0].derivatives == jc.Sensitivity(0.25)


def test_tolerance_file_settings_table(tmp_path):
    from jaxclear.tolerance.config import study_from_dict

    doc = {**INPUTS, "run": {"revolutions": 0.1}, "settings": {"rtol": 1e-7, "derivative_tolerance": 0.5}}
    kw = study_from_dict(doc, "t.toml", settings_options={"atol": 1e-12})
    assert (kw["settings"].rtol, kw["settings"].atol, kw["settings"].derivatives) == (1e-7, 1e-12, jc.Sensitivity(0.5))
    assert "settings" not in study_from_dict({**INPUTS, "run": {"revolutions": 0.1}}, "t.toml")


# --------------------------------------------------------------------------------------
# fit and posterior
# --------------------------------------------------------------------------------------

def test_fit_model_settings_keep_the_fits_policy_unless_derivatives_are_given():
    fit_default = fit_problem.default_fit_settings()
    m = fit_problem.model_settings(fit_default, anywhere=False)
    assert (m.rtol, m.atol) == (1e-8, 1e-11)
    assert m.derivatives == jc.Sensitivity(fit_problem.derivative_tolerance(1e-8)) == jc.Sensitivity(1.0)
    assert (m.output, m.onsets, m.throw, m.max_steps) == (fit_problem.FIT_OUTPUT, fit_problem.FIT_ONSETS, False,
                                                          fit_problem.MAX_STEPS)
    assert fit_problem.model_settings(fit_default, anywhere=True).max_steps == fit_problem.FREE_START_MAX_STEPS
    # at a looser rtol the policy gives the tenth
    assert fit_problem.model_settings(jc.settings(1.0), False).derivatives == jc.Sensitivity(0.1)
    # derivatives given are used as given; so are the output, onsets and step limit
    for given in (jc.Sensitivity(0.5), jc.ThroughLoop("forward")):
        assert fit_problem.model_settings(jc.settings(1.0, rtol=1e-8, derivatives=given), False).derivatives == given
    m = fit_problem.model_settings(jc.settings(1.0, output=jc.SampleBlock(4), onsets="step", max_steps=77), True)
    assert (m.output, m.onsets, m.max_steps) == (jc.SampleBlock(4), jc.StepOnsets(), 77)


def _fit_calls(monkeypatch, **kw):
    """``(settings dict, integration)`` that ``jc.fit`` hands to its problem (stopped there)."""
    from jaxclear.fitting import driver

    seen = []

    def build_problem(*args):
        seen.append((args[10], args[13]))
        raise Stop

    monkeypatch.setattr(driver, "build_problem", build_problem)
    with pytest.raises(Stop):
        jc.fit(None, MECH, **kw)
    return seen[0]


def test_fit_takes_settings_and_its_old_keywords_warn(monkeypatch):
    given = jc.settings(1.0, rtol=1e-7, atol=1e-10, derivatives=jc.Sensitivity(0.5))
    record, integration = _fit_calls(monkeypatch, settings=given)
    assert integration == given and (record["rtol"], record["atol"], record["max_steps"]) == (1e-7, 1e-10, None)
    assert record["integration"] == {"derivative_tolerance": 0.5}
    record, integration = _fit_calls(monkeypatch)  # no settings: the fit's own, the record of before
    assert integration == fit_problem.default_fit_settings() and "integration" not in record
    assert (record["rtol"], record["atol"], record["max_steps"]) == (1e-8, 1e-11, None)
    with pytest.warns(DeprecationWarning, match=r"fit\(rtol=, max_steps=\.\.\.\) is deprecated.*settings=jc.settings"):
        old = _fit_calls(monkeypatch, rtol=1e-7, max_steps=5000)
    new = _fit_calls(monkeypatch, settings=jc.settings(1.0, rtol=1e-7, atol=1e-11, max_steps=5000))
    assert old == new
    with pytest.raises(ParameterError, match=r"fit: both settings= and rtol=, atol= given"):
        jc.fit(None, MECH, settings=given, rtol=1e-7, atol=1e-10)


def test_a_free_start_fit_given_no_settings_runs_at_its_own_tolerances(monkeypatch):
    """Free starts (records of a laboratory) default to 1e-7 / 1e-10, the others keep 1e-8 / 1e-11;
    settings given are used as given in both, and the old keywords go over the free starts' own."""
    record, integration = _fit_calls(monkeypatch, start_state="free")
    assert integration == fit_problem.default_fit_settings(anywhere=True) and "integration" not in record
    assert (record["rtol"], record["atol"]) == (fit_problem.FREE_START_RTOL, fit_problem.FREE_START_ATOL) == (
        1e-7, 1e-10)
    given = jc.settings(1.0, rtol=1e-9, atol=1e-12)
    assert _fit_calls(monkeypatch, start_state="free", settings=given)[1] == given
    with pytest.warns(DeprecationWarning):
        record, _ = _fit_calls(monkeypatch, start_state="free", max_steps=5000)
    assert (record["rtol"], record["atol"], record["max_steps"]) == (1e-7, 1e-10, 5000)
    # the command line: the same defaults, shown by --help, a tolerance given goes over them
    from jaxclear.cli.fit import _settings

    text = " ".join(_sub("fit").format_help().split())
    assert "(default: 1e-8, 1e-7 with --start-state free)" in text
    assert "(default: 1e-11, 1e-10 with --start-state free)" in text
    s = _settings(build_parser().parse_args(["fit", "rec.csv", "--start-state", "free", "--max-steps", "9000"]))
    assert s == dataclasses.replace(fit_problem.default_fit_settings(anywhere=True), max_steps=9000)


def test_posterior_takes_settings_and_its_old_keywords_warn(monkeypatch):
    import importlib

    post = importlib.import_module("jaxclear.fitting.posterior")  # the module (the package's name is the function)
    seen = []

    def fit(*args, **kw):
        seen.append(kw["settings"])
        raise Stop

    monkeypatch.setattr(post, "fit", fit)
    given = jc.settings(1.0, rtol=1e-7, max_steps=5000)
    with pytest.raises(Stop):
        jc.posterior(None, MECH, settings=given)
    assert seen[-1] == given
    with pytest.warns(DeprecationWarning, match=r"posterior\(rtol=\.\.\.\)"), pytest.raises(Stop):
        jc.posterior(None, MECH, rtol=1e-7)
    # the step limit of before (200,000) where none is given
    assert seen[-1] == dataclasses.replace(fit_problem.default_fit_settings(), rtol=1e-7, max_steps=200_000)
    with pytest.raises(ParameterError, match=r"posterior: both settings= and atol= given"):
        jc.posterior(None, MECH, settings=given, atol=1e-9)


def _statistics_calls(monkeypatch, **kw):
    """``(settings its runs get, the plan)`` of ``jc.fit_statistics`` on a record of two tones (3
    revolutions of the preset), stopped where it would run the model."""
    from jaxclear.fitting import statistics_fit as sf

    seen = []

    def run_rows(mech, sensor, plan, rows, chunk, bar, settings):
        seen.append((settings, plan))
        raise Stop

    monkeypatch.setattr(sf, "run_rows", run_rows)
    t = np.arange(3 * 600) / 50e3  # 3 revolutions at 5000 rpm, 50 kHz
    data = {"time_s": t, "slider_acc_m_s2": np.sin(2 * np.pi * 900 * t) + 0.01 * np.cos(2 * np.pi * 7e3 * t)}
    with pytest.raises(Stop):
        jc.fit_statistics(data, MECH, revolutions=60, progress=False, **kw)
    return seen[-1]


def test_fit_statistics_takes_settings_and_replaces_only_what_it_owns(monkeypatch):
    from jaxclear.fitting.statistics_model import run_settings as statistics_run_settings

    given = jc.settings(7.0, t_start=1.0, n_out=9, rtol=1e-7, atol=1e-10, max_steps=12_345, progress=True,
                        solver="bosh3", onsets="step", derivative_tolerance=0.5)
    settings, plan = _statistics_calls(monkeypatch, settings=given)
    assert settings == given  # whole, to the runs
    s = statistics_run_settings(plan, settings)
    # what the statistics fit owns: each run from start-up to the last kept sample, its grid, no raise, no bar
    h = plan.dt / plan.oversample
    assert (s.t_start, s.n_out, s.throw, s.progress) == (0.0, plan.n_out, False, False)
    assert float(s.t_end) == pytest.approx((plan.n_out - 1) * h, rel=1e-15)
    assert s == dataclasses.replace(given, t_start=0.0, t_end=s.t_end, n_out=plan.n_out, throw=False, progress=False)
    # no settings: Settings' defaults (the runs of before: rtol 1e-6, atol 1e-9, 400,000 steps)
    settings, _ = _statistics_calls(monkeypatch)
    assert settings == default_settings()
    assert (settings.rtol, settings.atol, settings.max_steps) == (1e-6, 1e-9, 400_000)
    with pytest.warns(DeprecationWarning, match=r"fit_statistics\(rtol=, max_steps=\.\.\.\) is deprecated"):
        old, _ = _statistics_calls(monkeypatch, rtol=1e-7, max_steps=5000)
    assert old == jc.settings(1.0, rtol=1e-7, max_steps=5000)
    with pytest.raises(ParameterError, match=r"fit_statistics: both settings= and atol= given"):
        jc.fit_statistics(None, MECH, settings=given, atol=1e-9)
    with pytest.raises(ParameterError, match=r"fit_statistics: settings = 1e-07: expected a jaxclear.Settings"):
        jc.fit_statistics(None, MECH, settings=1e-7)


def test_the_settings_given_to_fit_statistics_reach_its_runs():
    """The runs of a statistics fit's grid (:func:`~jaxclear.fitting.statistics_model.run_rows`,
    what ``fit_statistics`` calls with its settings) integrated with a step limit of 50 stop
    there: status 1, "the solver reached max_steps", where the defaults run to the end."""
    from jaxclear.fitting.statistics_model import make_plan as statistics_plan
    from jaxclear.fitting.statistics_model import run_rows

    period = float(jc.crank_period(MECH))
    plan = statistics_plan(MECH, ("restitution",), period / 50, 1, period, 10, 1, 1, 0.0)
    _, status = run_rows(MECH, jc.Accelerometer(), plan, [[0.5, 0.0]], 1, None, jc.settings(1.0, max_steps=50))
    assert status.tolist() == [1] and jc.STATUS[1].startswith("the solver reached max_steps")


# --------------------------------------------------------------------------------------
# lyapunov, lyapunov_map, design, wear
# --------------------------------------------------------------------------------------

def test_lyapunov_takes_settings_by_its_name_and_the_old_one_warns():
    s = jc.settings(0.01)
    with pytest.raises(ParameterError, match=r"lyapunov: settings are required"):
        jc.lyapunov(MECH)
    with pytest.raises(ParameterError, match=r"both settings= and s="):
        jc.lyapunov(MECH, settings=s, s=s)
    with pytest.warns(DeprecationWarning, match=r"lyapunov\(s=\.\.\.\) is deprecated"), \
            pytest.raises(ParameterError, match=r"interval"):
        jc.lyapunov(MECH, s=s, interval=-1.0)  # reaches the checks after the settings
    # lyapunov_map: None is Settings' defaults (its span is its own); reaches the names' check
    with pytest.raises(ParameterError, match=r"values has 2 columns for 1 names"):
        jc.lyapunov_map(MECH, None, ["clearance"], [[1.0, 2.0]], revolutions=1)
    with pytest.warns(DeprecationWarning, match=r"lyapunov_map\(s=\.\.\.\)"), \
            pytest.raises(ParameterError, match=r"values has 2 columns"):
        jc.lyapunov_map(MECH, None, ["clearance"], [[1.0, 2.0]], revolutions=1, s=s)


def test_design_and_wear_take_one_settings_argument():
    for driver in (jc.design, jc.wear, jc.lyapunov, jc.lyapunov_map, jc.fit, jc.posterior, jc.tolerance_study):
        assert "settings" in inspect.signature(driver).parameters, driver.__name__
    assert "settings" in {f.name for f in dataclasses.fields(SweepConfig)}


# --------------------------------------------------------------------------------------
# the command line's option group
# --------------------------------------------------------------------------------------

INTEGRATING = ("simulate", "animate", "chaos", "wear", "design", "fit", "sweep", "tolerance")


def _sub(name):
    parser = build_parser()
    return next(a for a in parser._actions if hasattr(a, "choices") and isinstance(a.choices, dict)).choices[name]


@pytest.mark.parametrize("command", INTEGRATING)
def test_every_integrating_command_lists_the_group(command):
    text = _sub(command).format_help()
    for flag in FLAGS:
        assert flag in text, (command, flag)


def test_the_groups_defaults_are_read_from_settings():
    signature = inspect.signature(jc.Settings).parameters
    defaults = option_values(jc.Settings(t_end=1.0))
    args = build_parser().parse_args(["simulate"])
    for key in ("solver", "rtol", "atol", "max_steps"):
        assert getattr(args, key) == signature[key].default == defaults[key], key
    assert args.derivatives == defaults["derivatives"] == jc.Sensitivity().name
    assert args.derivative_tolerance == jc.Sensitivity().tolerance == defaults["derivative_tolerance"]
    assert args.output_sampling == jc.SampleLoop().name and args.onsets == jc.ExactOnsets().name
    assert given_options(args) == {} and settings_from_args(args) == default_settings()
    assert set(FLAGS.values()) <= set(OPTION_KEYS)


def test_the_group_converts_what_is_given():
    args = build_parser().parse_args(["simulate", "--derivative-tolerance", "0.5", "--onsets", "step", "--rtol",
                                      "1e-7", "--output-sampling", "block", "--solver", "dopri5"])
    s = settings_from_args(args)
    assert (s.rtol, s.derivatives, s.onsets, s.output, s.solver) == (
        1e-7, jc.Sensitivity(0.5), jc.StepOnsets(), jc.SampleBlock(), jc.SOLVERS["dopri5"]())
    from jaxclear.cli.simulate import settings_from

    s = settings_from(build_parser().parse_args(["simulate", "--revolutions", "0.5", "--derivatives", "forward"]),
                      MECH)
    assert s.derivatives == jc.ThroughLoop("forward") and float(s.t_end) == pytest.approx(
        0.5 * float(jc.crank_period(MECH)))
    # the fit: nothing given, the fit's own settings whole; a tolerance given, over the fit's own
    from jaxclear.cli.fit import _settings

    assert _settings(build_parser().parse_args(["fit", "rec.csv"])) is None
    s = _settings(build_parser().parse_args(["fit", "rec.csv", "--rtol", "1e-7"]))
    assert s == dataclasses.replace(fit_problem.default_fit_settings(), rtol=1e-7)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no deprecated spelling on the command line's way
        settings_from_args(args)


@pytest.mark.parametrize("driver", ["fit", "posterior", "fit_statistics", "tolerance_study", "lyapunov", "SweepConfig"])
def test_every_driver_refuses_settings_that_are_not_settings(driver, tmp_path):
    """One check of ``settings=`` (``jaxclear.integrate.check_settings``) in every driver: a
    tolerance given where the settings go names the driver and the expected type, before
    anything is read or compiled."""
    call = {"fit": lambda: jc.fit(None, MECH, settings=1e-7),
            "posterior": lambda: jc.posterior(None, MECH, settings=1e-7),
            "fit_statistics": lambda: jc.fit_statistics(None, MECH, settings=1e-7),
            "tolerance_study": lambda: jc.tolerance_study({}, MECH, settings=1e-7, out=str(tmp_path)),
            "lyapunov": lambda: jc.lyapunov(MECH, settings=1e-7),
            "SweepConfig": lambda: jc.SweepConfig(grid={"clearance": [1e-4]}, settings=1e-7, out=str(tmp_path))}[driver]
    with pytest.raises(ParameterError, match=r"settings = 1e-07: expected a jaxclear\.Settings \(jc\.settings\(t_end"):
        call()


def test_a_run_refuses_settings_that_are_not_settings_also_under_jit():
    """``jc.simulate`` and ``jc.sensitivities`` take their settings through the same check: a
    number or None where the settings go is a ParameterError naming the argument, not a
    ``TypeError`` from ``dataclasses.replace`` deep inside; under ``jax.jit`` too (a check of the
    settings' type, which is static there)."""
    import jax

    with pytest.raises(ParameterError, match=r"simulate: s = 1e-07: expected a jaxclear\.Settings"):
        jc.simulate(MECH, 1e-7)
    with pytest.raises(ParameterError, match=r"simulate: settings are required .*s=jc\.settings\(t_end"):
        jc.simulate(MECH, None)
    with pytest.raises(ParameterError, match=r"simulate: s = 3\.0: expected a jaxclear\.Settings"):
        jax.jit(lambda m: jc.simulate(m, 3.0).q)(MECH)
    with pytest.raises(ParameterError, match=r"sensitivities: s = 1e-07: expected a jaxclear\.Settings"):
        jc.sensitivities(MECH, ["clearance"], 1e-7)
