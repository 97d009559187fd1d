"""jc.fit_statistics: contact parameters from per-revolution statistics (Wood's synthetic
likelihood). The pieces against closed forms; the whole fit on a toy model whose statistics are
known in advance (fast, no simulation); on records of an independent simulator (fast: one short
record; slow: the three acceptance cases), benchmarks/lab_record.py, which shares no code with
jaxclear."""

import math
import time

import numpy as np
import pytest
from scipy.stats import multivariate_normal

import jaxclear as jc
from jaxclear.fitting import statistics as st
from jaxclear.fitting import statistics_fit as sf
from jaxclear.fitting.statistics_result import StatisticsFitResult, marginal_summary, verdict
from jaxclear.fitting.statistics_surrogate import Surrogate, evaluate

FS = 50e3
NB = 600  # samples per revolution at 5000 rpm and 50 kHz


def test_revolution_blocks_start_at_whole_revolutions():
    """Block k starts at round(k T / dt); a block holds floor(T / dt) samples; only whole blocks."""
    y = np.arange(999.0)
    assert st.whole_revolutions(999, 333.4) == 2 and st.whole_revolutions(1000, 333.4) == 3  # 667 + 333 = 1000
    b = st.revolution_blocks(y, 333.4)
    assert b.shape == (2, 333) and b[1, 0] == 333.0 and b[0, -1] == 332.0
    assert st.block_starts(4, 333.4).tolist() == [0, 333, 667, 1000]


def test_statistics_of_a_sine_are_the_closed_form_and_gain_shifts_them_exactly():
    """|A sin| over a whole period: quantile p is A sin(p pi / 2) (uniform phase), the maximum A;
    a gain g adds w log g (w = 1 peaks, 2 band powers) and a bias nothing (rounding: 1e-12).
    Sampled 600 times per period, |sin| takes values 2 pi / 600 apart at most: 1e-2 relative
    near the 0.99 quantile (where the slope cos(0.495 pi) is smallest, values crowd), so 2e-3 in
    log for the others and 1e-2 there."""
    t = np.arange(NB) / FS
    a = 7.0e3
    x = a * np.sin(2 * np.pi * t / (NB / FS))[None, :]
    s = st.block_statistics(x, FS, ("peaks",))[0]
    expect = np.log(a * np.sin(np.array(st.PEAK_LEVELS) * np.pi / 2))
    np.testing.assert_allclose(s[:2], expect[:2], atol=2e-3)
    np.testing.assert_allclose(s[2:], expect[2:], atol=1e-2)
    rng = np.random.default_rng(0)
    blocks = rng.standard_normal((3, NB)) * 1e3
    kinds = ("peaks", "spectrum")
    base = st.block_statistics(blocks, FS, kinds)
    shifted = st.block_statistics(1.37 * blocks + 55.0, FS, kinds)
    np.testing.assert_allclose(shifted - base, np.broadcast_to(np.log(1.37) * st.statistic_weights(kinds), base.shape),
                               atol=1e-12)
    assert len(st.statistic_names(kinds, FS, NB)) == base.shape[1] == 13


def test_white_noise_band_powers_are_their_expectation():
    """Welch's density of white noise of variance s^2 is s^2 * 2 / fs at every interior
    frequency (half that at the Nyquist bin): a band's sum of bins is that times its bin count.
    A one-bin band of one revolution (11 half-overlapping segments) scatters by about 30 %, its
    mean over 400 revolutions by 1.5 %: tolerance 5 %. The first band (0-1 kHz) is left out:
    the segments' linear detrend removes most of its 500 Hz bin."""
    rng = np.random.default_rng(1)
    s = 300.0
    blocks = rng.standard_normal((400, NB)) * s
    f = np.fft.rfftfreq(st.segment_length(NB), 1 / FS)
    e = st.band_edges(FS, NB)
    p = np.exp(st.block_statistics(blocks, FS, ("spectrum",))).mean(axis=0)
    for k, (lo, hi) in enumerate(zip(e[:-1], e[1:])):
        inside = (f >= lo) & ((f < hi) if k < len(e) - 2 else (f <= hi))
        interior = inside & (f > 0) & (f < FS / 2)
        expect = s**2 * 2 / FS * (interior.sum() + 0.5 * (inside.sum() - interior.sum()))
        assert k == 0 or abs(p[k] / expect - 1) < 0.05, (k, p[k] / expect)


def test_synthetic_loglik_is_the_normal_density_up_to_a_constant():
    """log L(t) - log L(t') equals the difference of the normal log densities of the observed mean
    under N(mu + w t, Sigma (1/n_r + 1/n_m) / c) (rounding: 1e-9)."""
    rng = np.random.default_rng(2)
    s = rng.standard_normal((40, 3)) @ np.array([[1.0, 0.3, 0.0], [0.0, 1.0, 0.2], [0.0, 0.0, 0.5]])
    obs, w, n_r = np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 2.0]), 12
    mu, cov = st.moments(s)
    c = st.precision_factor(40, 3)
    t = np.array([-0.1, 0.0, 0.2])
    ll, chi2 = st.synthetic_loglik(st.quadratic_terms(obs, mu, cov, w), t, c / (1 / n_r + 1 / 40))
    direct = [multivariate_normal(mu + w * ti, cov * (1 / n_r + 1 / 40) / c).logpdf(obs) for ti in t]
    np.testing.assert_allclose(ll - ll[0], np.array(direct) - direct[0], atol=1e-9)
    assert np.all(chi2 >= 0)
    bad = st.quadratic_terms(obs, mu, np.zeros((3, 3)), w)  # singular: no likelihood
    assert np.isinf(st.synthetic_loglik(bad, t, 1.0)[0]).all()


def test_marginal_summary_matches_the_closed_forms_of_a_cellwise_constant_density():
    """Equal masses on an even grid: a uniform density over the cells' span. Linear: mean the
    midpoint, std span / sqrt(12), 5 % point 5 % along. Log: E = (e^b - e^a) / (b - a)."""
    v = np.linspace(1.0, 3.0, 5)  # cells span [0.75, 3.25]
    p = np.full(5, 0.2)
    s = marginal_summary(v, p, "none")
    assert s["mean"] == pytest.approx(2.0, rel=1e-12) and s["std"] == pytest.approx(2.5 / math.sqrt(12), rel=1e-12)
    assert s["q05"] == pytest.approx(0.75 + 0.05 * 2.5, rel=1e-12)
    u = np.linspace(0.0, 2.0, 5)  # log grid: cells span u in [-0.25, 2.25]
    s = marginal_summary(np.exp(u), p, "log")
    a, b = -0.25, 2.25
    assert s["mean"] == pytest.approx((math.exp(b) - math.exp(a)) / (b - a), rel=1e-12)
    assert s["q95"] == pytest.approx(math.exp(a + 0.95 * (b - a)), rel=1e-12)
    s = marginal_summary(np.array([0.2, 0.5, 0.8]), np.array([0.0, 1.0, 0.0]), "logit")
    assert s["q05"] < 0.5 < s["q95"] and s["std"] > 0  # a one-cell posterior keeps its cell's width


def test_noise_profile_finds_the_level_of_a_known_problem():
    """Statistics whose mean is mu = (log s, 2 log s) on a grid of log s (exactly interpolated by
    the cubic spline) and an observation made at s* = 0.37: the golden-section profile returns s*
    (to 1e-4: the bracket shrinks 0.618^30 times)."""
    ls = np.linspace(np.log(0.1), np.log(1.0), 7)
    u = np.array([0.0, 1.0, 2.0, 3.0])
    mu = np.zeros((4, 7, 2))
    mu[..., 0], mu[..., 1] = ls[None, :], 2 * ls[None, :]
    cov = np.broadcast_to(np.diag([0.01, 0.04]), (4, 7, 2, 2)).copy()
    sur = Surrogate([u, ls], mu, cov)
    obs = np.array([np.log(0.37), 2 * np.log(0.37)])
    ll, chi2, got = evaluate(sur, np.array([[0.5], [2.5]]), ls, obs, np.array([1.0, 2.0]), np.zeros(1), np.zeros(1),
                             1.0)
    np.testing.assert_allclose(np.exp(got), 0.37, rtol=1e-4)
    assert np.all(chi2 < 1e-6)


def test_verdict_flags_edges_failed_neighbours_and_misfit():
    """The verdict's rules on a hand-made result: mass at a grid end, failed nodes next to the
    posterior's mass, a chi-squared far in the tail."""
    grid = {"stiffness": np.geomspace(1e10, 1e11, 9)}
    marg = np.array([0.5, 0.3, 0.2, 0, 0, 0, 0, 0, 0])
    res = StatisticsFitResult(
        free=("stiffness",), estimates={}, map={}, std={}, intervals={}, grid=grid, nodes=grid, posterior=marg,
        log_likelihood=np.zeros(9), marginals={"stiffness": marg}, noise={"estimate": 1.0, "profiled": False},
        noise_profile=np.zeros(9), statistics=["a"] * 13, observed=np.zeros(13), model_mean=np.zeros(13), chi2=80.0,
        record_revolutions=3, model_revolutions=40, failed_points=[{"stiffness": 1.3e10, "status": 1}])
    summaries = {"stiffness": marginal_summary(grid["stiffness"], marg, "log")}
    failed = np.zeros(9, bool)
    failed[1] = True
    failures, notes = verdict(res, summaries, failed, marg, True)
    text = " ".join(failures)
    assert "grid's first value" in text and "widen grid['stiffness']" in text
    assert "1 of 9 grid points failed to run (status [1])" in text
    assert "out of the model's reach: chi2 = 80.0 for 13 statistics" in text
    assert any("3 revolutions" in n for n in notes)


# ---------------------------------------------------------------------------------------------
# the whole fit on a toy model: the engine's runs replaced by signals whose statistics are known
# ---------------------------------------------------------------------------------------------

def _toy_blocks(k_rel, c, count, seed):
    """Revolutions of a toy 'mechanism': a crank harmonic (parameter-free), smoothed noise (an
    8-sample moving average, below ~6 kHz) whose amplitude grows as sqrt(stiffness), and a
    band-pass noise (3-sample minus 8-sample moving averages: none at fs/3 = 16.7 kHz and above,
    where white measurement noise is alone) growing with restitution."""
    rng = np.random.default_rng(seed)
    t = np.arange(NB) / FS
    z1, z2 = rng.standard_normal((2, count, NB))
    ma = lambda z, n: np.apply_along_axis(lambda r: np.convolve(r, np.ones(n) / n, mode="same"), 1, z)  # noqa: E731
    return (1e4 * np.sin(2 * np.pi * t / (NB / FS))[None, :] + 3e3 * math.sqrt(k_rel) * ma(z1, 8)
            + 4e3 * (0.5 + 2 * (c - 0.5)) * (ma(z2, 3) - ma(z2, 8)))


def test_toy_fit_covers_the_truth_reports_failed_nodes_and_the_noise(monkeypatch):
    """With the engine replaced by the toy model (every node's runs drawn from it; one node
    'fails'), a record of 30 toy revolutions at stiffness 1.3 x nominal, restitution 0.8, gain
    1.03, bias 0.5 and noise 1500 m/s^2 is fitted: the truth lies in every 90 % interval and within
    3 std, the noise is found within 10 %, the failed node is reported and excluded."""
    mech = jc.preset("flores-slider-crank")
    k0 = float(jc.params.get(mech, "stiffness"))

    def fake_runs(mech_, sensor, plan, rows, chunk, bar, settings):
        out = np.stack([_toy_blocks(r[0] / k0, r[1], plan.blocks, seed=int(1e6 * r[1]) + int(r[0] / k0 * 1e3) + 7919
                                    * int(round(r[2] * 1e12))) for r in rows])
        status = np.where((np.abs(rows[:, 0] - rows[:, 0].max()) < 1) & (np.abs(rows[:, 1] - rows[:, 1].min()) < 1e-9),
                          1, 0)
        return out, status.astype(np.int32)

    monkeypatch.setattr(sf, "run_rows", fake_runs)
    n = 30
    rng = np.random.default_rng(11)
    y = (1.03 * _toy_blocks(1.3, 0.8, n, seed=99).reshape(-1) + 0.5) + rng.normal(0.0, 1500.0, n * NB)
    data = {"time_s": np.arange(n * NB) / FS, "slider_acc_m_s2": y}
    res = jc.fit_statistics(data, mech, free=("stiffness", "restitution", "sensor_gain"),
                            grid={"stiffness": f"{k0 / 3}:{3 * k0}:7", "restitution": "0.5:0.95:7"}, revolutions=60,
                            progress=False)
    truth = {"stiffness": 1.3 * k0, "restitution": 0.8, "sensor_gain": 1.03}
    for name, value in truth.items():
        lo, hi = res.intervals[name]
        assert lo <= value <= hi, (name, res.summary())
        assert abs(res.estimates[name] - value) < 3 * res.std[name], (name, res.summary())
    assert abs(res.noise["estimate"] / 1500.0 - 1) < 0.1, res.noise
    assert res.failed_points == [{"stiffness": pytest.approx(3 * k0), "restitution": 0.5, "status": 1}]
    assert any("1 of 49 grid points failed" in s for s in res.failures + res.notes)
    assert res.record_revolutions == n and res.model_revolutions == 60 and res.settings["replicates"] == 3
    assert res.posterior.shape == (25, 25, 241) and abs(res.posterior.sum() - 1) < 1e-12
    assert res.chi2 < 40 and res.ok, res.summary()


def test_inputs_are_checked_before_any_run():
    mech = jc.preset("flores-slider-crank")
    t = np.arange(int(1.5 * NB)) / FS
    short = {"time_s": t, "slider_acc_m_s2": np.sin(2 * np.pi * 900 * t)}
    with pytest.raises(jc.ParameterError, match=r"holds 1 whole crank revolution.*allowed range \[2, inf\)"):
        jc.fit_statistics(short, mech, progress=False)
    t = np.arange(3 * NB) / FS
    data = {"time_s": t, "slider_acc_m_s2": np.sin(2 * np.pi * 900 * t) + 0.01 * np.cos(2 * np.pi * 7e3 * t)}
    with pytest.raises(jc.ParameterError, match="'sensor_bias' cannot be fitted from per-revolution statistics"):
        jc.fit_statistics(data, mech, free=("stiffness", "sensor_bias"), progress=False)
    with pytest.raises(jc.ParameterError, match=r"revolutions = 10 outside the allowed range \[18, inf\)"):
        jc.fit_statistics(data, mech, revolutions=10, progress=False)
    with pytest.raises(jc.ParameterError, match="grid\\['restitution'\\] = '0.5:1.2:5': needs 0 < LOW < HIGH < 1"):
        jc.fit_statistics(data, mech, grid={"restitution": "0.5:1.2:5"}, progress=False)
    with pytest.raises(jc.ParameterError, match="priors given for \\['sensor_gain'\\], which are not free"):
        jc.fit_statistics(data, mech, priors={"sensor_gain": "lognormal:1:2"}, progress=False)
    with pytest.raises(jc.ParameterError, match="statistics = \\['peak'\\]"):
        jc.fit_statistics(data, mech, statistics=("peak",), progress=False)
    fast = {**data, "crank_angle_rad": 1.01 * 523.5987755982989 * t}
    with pytest.raises(jc.ParameterError, match="crank turns at .* differ by more than 0.001"):
        jc.fit_statistics(fast, mech, progress=False)


# ---------------------------------------------------------------------------------------------
# records of the independent simulator (benchmarks/lab_record.py, NumPy/SciPy only)
# ---------------------------------------------------------------------------------------------

def _lab_data(factor, c_r, seed, revolutions):
    """A record of the independent simulator 5 revolutions after start-up, from 37 degrees, through
    a 10 kHz 2nd-order Butterworth sensor, gain 1.03, bias 0.5 m/s^2, 20 dB noise at 50 kHz."""
    import lab_record  # benchmarks/ (on sys.path by conftest.py)

    rec = lab_record.make_record(stiffness_factor=factor, c_r=c_r, seed=seed, revolutions_before=5,
                                 duration=revolutions * 60.0 / 5000.0)
    data = {k: rec[k] for k in ("time_s", "slider_acc_m_s2", "crank_angle_rad")}
    return data, rec["truth"]


@pytest.mark.extended
def test_fit_of_a_short_record_of_the_independent_simulator():
    """8 revolutions (96 ms) of the independent simulator at stiffness 1 x nominal and restitution
    0.9 (its case 3), the gain known; 4 x 5 nodes (stiffness a factor 3 either side, restitution
    0.6-0.98), 40 model revolutions per node. The truth lies in both 90 % intervals and within 3
    std; the restitution is found to better than 0.05 (one std; measured 0.037), a sixth of its
    grid's span. Measured: 0.873 +- 0.037 and stiffness 0.83 +- 0.46 x nominal (8 revolutions through
    a 10 kHz sensor say little about it), about 1 minute on 2 loaded cores (the record 30 s)."""
    mech = jc.preset("flores-slider-crank")
    k0 = float(jc.params.get(mech, "stiffness"))
    data, truth = _lab_data(1.0, 0.9, 3, 8)
    res = jc.fit_statistics(data, mech, sensor=jc.Accelerometer(10e3, order=2, gain=1.03),
                            grid={"stiffness": f"{k0 / 3}:{3 * k0}:4", "restitution": "0.6:0.98:5"}, revolutions=40,
                            progress=False)
    for name, value in (("stiffness", truth["stiffness"]), ("restitution", truth["c_r"])):
        lo, hi = res.intervals[name]
        assert lo <= value <= hi, (name, res.summary())
        assert abs(res.estimates[name] - value) < 3 * res.std[name], (name, res.summary())
    assert res.std["restitution"] < 0.05, res.summary()
    assert res.record_revolutions == 8 and res.model_revolutions == 40 and not res.failed_points


#: The acceptance: the three truths of the laboratory records (stiffness factor, restitution, seed).
ACCEPTANCE = [(0.8, 0.75, 1), (1.25, 0.85, 2), (1.0, 0.9, 3)]


@pytest.mark.slow
@pytest.mark.parametrize("factor,c_r,seed", ACCEPTANCE)
def test_statistics_fit_of_a_long_laboratory_record(factor, c_r, seed):
    """40 revolutions (0.48 s) of the independent simulator from its 5th revolution; stiffness,
    restitution and gain free, 9 x 9 nodes (stiffness a factor 4 either side of nominal,
    restitution 0.4-0.98), 200 model revolutions per node. Each truth lies within its 90 %
    interval or within 2 std of the estimate (a calibrated posterior misses a 90 % interval one
    time in ten; 2 std bounds a 5 % miss), every error within 3 std, and the fit is a result."""
    mech = jc.preset("flores-slider-crank")
    k0 = float(jc.params.get(mech, "stiffness"))
    t0 = time.perf_counter()
    data, truth = _lab_data(factor, c_r, seed, 40)
    made = time.perf_counter() - t0
    res = jc.fit_statistics(data, mech, free=("stiffness", "restitution", "sensor_gain"),
                            sensor=jc.Accelerometer(10e3, order=2, gain=1.03),
                            grid={"stiffness": f"{k0 / 4}:{4 * k0}:9", "restitution": "0.4:0.98:9"}, revolutions=200,
                            progress=False)
    true = {"stiffness": truth["stiffness"], "restitution": c_r, "sensor_gain": 1.03}
    line = [f"case K {factor} c_r {c_r}: record {made:.0f} s, fit {res.wall_time_s:.0f} s, chi2 {res.chi2:.1f}, "
            f"noise {res.noise['estimate']:.0f} (true {truth['noise_std']:.0f})"]
    for name, value in true.items():
        lo, hi = res.intervals[name]
        z = (res.estimates[name] - value) / res.std[name]
        line.append(f"{name} {res.estimates[name]:.5g} +- {res.std[name]:.3g} [{lo:.5g}, {hi:.5g}] true {value:.5g} "
                    f"z {z:+.2f}")
        assert lo <= value <= hi or abs(z) < 2.0, (name, res.summary())
        assert abs(z) < 3.0, (name, res.summary())
    print("\n  ".join(line))
    assert res.ok, res.summary()


def test_a_prior_of_the_value_becomes_a_density_of_the_grid_coordinate():
    """A uniform prior on restitution in (0, 1) is, in u = logit(c), the logistic density c (1 - c);
    a log-normal on stiffness is, in u = log K, normal in u (closed forms; rounding 1e-12)."""
    c = np.array([0.3, 0.6, 0.9])
    np.testing.assert_allclose(sf._log_prior("restitution", c, "uniform:0:1", "logit"), np.log(c * (1 - c)), atol=1e-12)
    k = np.array([1e10, 5e10, 2e11])
    s = math.log(3.0)
    expect = -0.5 * ((np.log(k) - math.log(5e10)) / s) ** 2 - math.log(s) - 0.5 * math.log(2 * math.pi)
    np.testing.assert_allclose(sf._log_prior("stiffness", k, "lognormal:5e10:3", "log"), expect, atol=1e-12)
