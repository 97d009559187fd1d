"""One parameter registry (issue 40, item 4): every class declares its named parameters next to
its fields (``PARAMETERS``), :mod:`jaxclear.params` composes them, and a new force element is one
class in one file. The toy element here is defined in this file only and registered nowhere
(not in the mechanism files' ``CONNECTORS``): names, values, ranges (eager and inside ``jit``),
the differentiable names, ``jax.grad`` of a run, the structure check, the drawing, a sweep and a
fit all find it through its declaration."""

from __future__ import annotations

import warnings
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear import params
from jaxclear._parameters import Parameter
from jaxclear.analysis.structure import check_mechanism
from jaxclear.contact.registry import LAWS
from jaxclear.drawing import plot_mechanism
from jaxclear.model.connectors import CONNECTORS, AbstractPointPair

M, K, L0 = 2.0, 800.0, 0.5  # kg, N/m, m
TIGHT = dict(rtol=1e-10, atol=1e-13, allow_free_dof=True)


class ToySpring(AbstractPointPair):
    """A linear spring between two points: tension k (L - L_0) [N]. The whole element: its
    fields, its declared parameters, its coordinate and its law."""

    name: str = eqx.field(static=True)
    body_a: str = eqx.field(static=True)
    point_a: str = eqx.field(static=True)
    body_b: str = eqx.field(static=True)
    point_b: str = eqx.field(static=True)
    k: jax.Array
    l0: jax.Array

    OUTPUTS: ClassVar[dict[str, str]] = {"force": "N", "length": "m", "rate": "m/s", "power": "W"}
    PARAMETERS: ClassVar[dict[str, Parameter]] = {
        "toy_stiffness": Parameter("k", "N/m", low=0.0, transform="log", doc="stiffness of the toy spring"),
        "toy_length": Parameter("l0", "m", low=0.0, low_open=True, high=1.0, doc="rest length of the toy spring"),
    }

    def __init__(self, name, body_a, point_a, body_b, point_b, k, l0):
        self.name, self.body_a, self.point_a, self.body_b, self.point_b = name, body_a, point_a, body_b, point_b
        self.k, self.l0 = jnp.asarray(k, dtype=float), jnp.asarray(l0, dtype=float)
        self._validate()

    def coordinates(self, mech, q):
        gap = self.gap(mech, q)
        return jnp.sqrt(jnp.sum(gap**2))[None]

    def law(self, d, ddot):
        return self.k * (d - self.l0)


def toy_oscillator(k=K, y0=-(L0 + 0.01)):
    """A block on a vertical guide hung from the ground point O by the toy spring (1 dof: y)."""
    block = jc.Body("block", M, 0.01, points={"P": (0.0, 0.0)}, position=(0.0, y0, 0.0))
    guide = jc.Translational("ground", "O", "block", "P", axis=(0.0, 1.0))
    spring = ToySpring("t", "ground", "O", "block", "P", k=k, l0=L0)
    return jc.Mechanism([block], joints=[guide], loads=[spring], ground_points={"O": (0.0, 0.0)}, gravity=(0.0, 0.0),
                        name="toy")


def test_the_toy_element_is_registered_nowhere_and_named_through_its_declaration():
    mech = toy_oscillator()
    assert ToySpring not in CONNECTORS.values() and ToySpring not in params.REGISTERED
    assert "toy_stiffness" not in params.parameter_names()  # the catalogue is the registered classes'
    names = params.names(mech)
    assert names[-2:] == ["toy_stiffness:t", "toy_length:t"]
    assert jc.differentiable_names(mech) == names
    assert float(params.get(mech, "toy_stiffness:t")) == K
    new = params.replace(mech, "toy_stiffness:t", 123.0)
    assert float(new.loads[0].k) == 123.0 and float(params.get(new, "toy_stiffness:t")) == 123.0
    assert float(params.get(params.replace_many(mech, {"toy_length:t": 0.4}), "toy_length:t")) == 0.4
    assert params.info("toy_stiffness:t", mech).unit == "N/m" and params.info("toy_length:t", mech).high == 1.0
    assert params.to_unconstrained("toy_stiffness:t", 2.0, mech) == pytest.approx(np.log(2.0))
    params.check_name(mech, "toy_length:t")
    with pytest.raises(jc.ParameterError, match=r"unknown parameter 'toy_stifness:t'; did you mean 'toy_stiffness:t'"):
        params.get(mech, "toy_stifness:t")
    with pytest.raises(jc.ParameterError, match=r"no force element .* named 'u'.*those with 'toy_stiffness': \['t'\]"):
        params.get(mech, "toy_stiffness:u")
    with pytest.raises(jc.ParameterError, match="design variable 'toy_stiffness:x'"):
        params.check_name(mech, "toy_stiffness:x", context="design variable 'toy_stiffness:x'")
    assert not params.is_derived(mech, "toy_stiffness:t")


def test_the_toy_element_range_is_checked_eagerly_and_inside_jit():
    mech = toy_oscillator()
    np.testing.assert_array_equal(params.validate(mech, "toy_stiffness:t", [0.0, 5.0]), [0.0, 5.0])
    with pytest.raises(jc.ParameterError, match=r"toy_stiffness:t = -1 N/m is outside the allowed range \[0, inf\)"):
        params.validate(mech, "toy_stiffness:t", [-1.0])
    with pytest.raises(jc.ParameterError, match=r"toy_length:t = 1.5 m is outside the allowed range \(0, 1\]"):
        params.validate(mech, "toy_length:t", 1.5)
    with pytest.raises(jc.ParameterError, match=r"k \(toy_stiffness:t\) = -2 N/m is outside"):
        ToySpring("t", "ground", "O", "block", "P", k=-2.0, l0=L0)  # the constructor's check
    s = jc.settings(0.01, n_out=3, throw=False, **TIGHT)
    status = jax.jit(lambda k: jc.simulate(params.replace(mech, "toy_stiffness:t", k), s).status)
    assert jc.STATUS[int(status(-1.0))].startswith("invalid parameter")
    assert int(status(10.0)) == 0
    said = params.replace(mech, "toy_length:t", 2.0).failed_check()
    assert "toy_length:t" in said and "(0, 1]" in said


def test_grad_of_a_run_with_respect_to_the_toy_stiffness_against_central_differences():
    """``jax.grad`` of the block's final height with respect to ``toy_stiffness:t`` (the
    error-controlled sensitivities, transposed) against central differences of runs at rtol
    1e-10, over steps h from 1e-1 to 1e-7 of the value. The differences' error falls as h^2 (the
    truncation: measured 1.2e-2, 1.2e-4, 1.2e-6 relative at 1e-1, 1e-2, 1e-3) down to a plateau
    (1.2e-8, 4.2e-9, 2.0e-8 at 1e-4, 1e-5, 1e-6), below which the runs' errors, about 1e-13 m over
    a difference of 2 h |dy/dk|, take over and grow as 1/h: at 1e-7 measured 2.7e-8 on one machine
    and 1.7e-7 on another (the runs' rounding differs between CPUs), so that step is held only to
    the rounding bound 5e-7 (a run error 3 times the 1e-13 m). The gradient is the plateau's value."""
    mech = toy_oscillator()
    s = jc.settings(0.3, n_out=2, **TIGHT)

    def y_end(k):
        return jc.simulate(params.replace(mech, "toy_stiffness:t", k), s).q[-1, 1]

    grad = float(jax.grad(y_end)(jnp.asarray(K)))
    run = jax.jit(y_end)
    errors = {}
    for rel in (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7):
        h = rel * K
        fd = (float(run(K + h)) - float(run(K - h))) / (2 * h)
        errors[rel] = abs(fd - grad) / abs(grad)
    print({f"{r:g}": f"{e:.2e}" for r, e in errors.items()})
    assert abs(grad) > 1e-5
    for big, small in ((1e-1, 1e-2), (1e-2, 1e-3)):  # truncation: the error falls 100-fold per 10-fold step
        assert 50 < errors[big] / errors[small] < 200
    plateau = [errors[r] for r in (1e-4, 1e-5, 1e-6)]
    assert max(plateau) < 5e-8 and min(plateau) < 1e-8  # the plateau, where the gradient lies
    assert errors[1e-7] < 5e-7  # the rounding side: the runs' own errors over a difference of 2 h


def test_the_toy_element_in_the_structure_check_and_the_drawing(tmp_path):
    mech = toy_oscillator()
    described = check_mechanism(mech, allow_free_dof=True)
    assert described["loads"] == ["ToySpring 't'"] and described["dof"] == 1
    q = np.array([0.0, -(L0 + 0.01), 0.0])
    fig = plot_mechanism(tmp_path / "toy.png", mech, q)
    lines = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_label() == "ToySpring 't'"]
    assert len(lines) == 1  # drawn by AbstractPointPair.sketch: a straight line between its points
    np.testing.assert_allclose(np.asarray(lines[0].get_xydata()), [[0.0, 0.0], [0.0, -(L0 + 0.01)]], atol=1e-12)
    assert (tmp_path / "toy.png").exists()


def test_every_law_declares_its_stiffness_leaf_and_every_name_one_meaning():
    """The stiffness each law declares is the leaf its ``stiffness_parameter`` names; the
    catalogue composed from the registered classes is the one ``INFO`` lists (51 names)."""
    for cls, *_ in LAWS.values():
        assert cls.PARAMETERS["stiffness"].field == cls.stiffness_parameter, cls
    assert len(params.INFO) == 51 and params.parameter_names() == sorted(params.INFO)
    joint = jc.preset("flores-slider-crank").clearance_joints[0]
    table = joint.parameters()  # the joint answers for its law and friction (leaf paths law.*, friction.*)
    assert table["restitution"].field == "law.restitution" and table["friction"].field == "friction.coefficient"


def test_sensitivities_takes_the_order_of_parameter_grad_and_warns_for_the_old_one():
    mech = toy_oscillator()
    s = jc.settings(0.05, n_out=2, **TIGHT)
    out = lambda sol, m: sol.q[-1, 1]  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        _, new = jc.sensitivities(mech, ["toy_stiffness:t"], s, output=out)
    with pytest.warns(DeprecationWarning, match=r"jc.sensitivities\(mech, names, settings\)"):
        _, old = jc.sensitivities(mech, s, ["toy_stiffness:t"], output=out)
    assert float(new["toy_stiffness:t"]) == float(old["toy_stiffness:t"])
    _, kw = jc.sensitivities(mech, s=s, names=["toy_stiffness:t"], output=out)
    assert float(kw["toy_stiffness:t"]) == float(new["toy_stiffness:t"])


# ---- the toy element's parameter swept and fitted (the drivers ask the registry with the mechanism)

G, AMPLITUDE = 9.81, 0.01  # m/s^2; m


def toy_on_a_crank(k=K):
    """The toy oscillator beside a crank turning once a second (a sweep runs whole crank
    revolutions), under gravity: the block starts at rest with the spring at its rest length, so
    ``y(t) = -L0 - (M g / k) (1 - cos(sqrt(k / M) t))``, lowest at ``-L0 - 2 M g / k``."""
    crank = jc.Body("crank", 1.0, 0.01, {"O": (0.0, 0.0)})
    block = jc.Body("block", M, 0.01, points={"P": (0.0, 0.0)}, position=(1.0, -L0, 0.0))
    return jc.Mechanism([crank, block], joints=[jc.Revolute(jc.GROUND, "C", "crank", "O"),
                                                jc.Translational("ground", "O", "block", "P", axis=(0.0, 1.0))],
                        drivers=[jc.AngleDriver("crank", 2 * np.pi, 0.0)],
                        loads=[ToySpring("t", "ground", "O", "block", "P", k=k, l0=L0)],
                        ground_points={"O": (1.0, 0.0), "C": (0.0, 0.0)}, gravity=(0.0, -G), name="toy-crank")


def toy_beside_a_clearance_joint(k=K):
    """The toy oscillator beside a crank held in a clearance joint (a fit needs one), without
    gravity: the crank's centroid on its journal, the journal centred, nothing pushes it, so the
    joint never closes. The block starts at rest ``AMPLITUDE`` below the rest length:
    ``a_y(t) = AMPLITUDE (k / M) cos(sqrt(k / M) t)``."""
    crank = jc.Body("crank", 1.0, 0.01, {"O": (0.0, 0.0)})
    block = jc.Body("block", M, 0.01, points={"P": (0.0, 0.0)}, position=(1.0, -(L0 + AMPLITUDE), 0.0))
    joint = jc.ClearanceJoint(jc.GROUND, "C", "crank", "O", bearing_radius=0.010, journal_radius=0.0095,
                              law=jc.make_law("lankarani-nikravesh", restitution=0.9))
    return jc.Mechanism([crank, block], joints=[jc.Translational("ground", "O", "block", "P", axis=(0.0, 1.0))],
                        drivers=[jc.AngleDriver("crank", 2 * np.pi, 0.0)], clearance_joints=[joint],
                        loads=[ToySpring("t", "ground", "O", "block", "P", k=k, l0=L0)],
                        ground_points={"O": (1.0, 0.0), "C": (0.0, 0.0)}, gravity=(0.0, 0.0), name="toy-fit")


def test_the_toy_stiffness_swept_gives_the_closed_form_deflection(tmp_path):
    """``toy_stiffness:t`` swept over 200, 800, 3200 N/m (one revolution, 1 s): the block's lowest
    point is ``-L0 - 2 M g / k`` (twice the static deflection: 0.196, 0.049, 0.012 m). Tolerance:
    the lowest sample lies within half a sample spacing (0.25 ms) of the true lowest point, so
    it misses the deflection by at most ``(omega dt / 2)^2 / 4`` of it, 2.5e-5 at the stiffest
    (omega 40 rad/s); the runs' error at rtol 1e-9 is far below. Bounds 5e-5 relative. The toy's
    unit and description reach the results (``results.nc``, the DataFrame, the axis label) from the
    registry asked with the mechanism, through the manifest."""
    from jaxclear import sweep

    mech = toy_on_a_crank()
    stiffness = [200.0, 800.0, 3200.0]
    cfg = sweep.SweepConfig(mechanism=mech, grid={"toy_stiffness:t": stiffness}, revolutions=1,
                            samples_per_revolution=2000, ideal_reference=False, channels=["point:block:P:pos:y"],
                            progress=False, out=str(tmp_path / "sweep"), settings=jc.settings(1.0, rtol=1e-9, atol=1e-12))
    res = sweep.run_sweep(cfg)
    k = np.asarray(res.table["toy_stiffness:t"])
    np.testing.assert_array_equal(k, stiffness)
    assert list(res.table["status"]) == [0, 0, 0]
    deflection = -L0 - np.asarray(res.table["min__point_block_P_pos_y"])
    np.testing.assert_allclose(deflection, 2 * M * G / k, rtol=5e-5)
    np.testing.assert_allclose(res.table["max__point_block_P_pos_y"], -L0, atol=1e-9)  # it turns at the rest length
    # its unit and description in the results: results.nc as run_sweep wrote it (readable: no clearance
    # joint, so no Poincare variable with a dimension of length 0), and the folder read back without the
    # mechanism (res: the manifest keeps what the registry answered with it)
    toy = {"units": "N/m", "long_name": "stiffness of the toy spring (toy_stiffness:NAME)"}  # params.info's
    ds = sweep.open_dataset(cfg.out)
    assert ds["toy_stiffness:t"].attrs == toy and "poincare" not in ds
    assert res.to_xarray()["toy_stiffness:t"].attrs == toy
    assert res.to_dataframe().attrs["units"]["toy_stiffness:t"] == "N/m"
    label = sweep.axis_label("toy_stiffness:t", sweep.column_records(res.manifest))
    assert label == (f"{toy['long_name']} [N/m]", 1.0)
    # the sweep checks the toy's declared range, and knows speed and the toy's name apart
    with pytest.raises(jc.ParameterError, match=r"toy_stiffness:t = -1 N/m is outside the allowed range \[0, inf\)"):
        sweep.SweepConfig(mechanism=mech, grid={"toy_stiffness:t": [-1.0, 1.0]}, ideal_reference=False)
    with pytest.raises(jc.ParameterError, match=r"parameters 'speed' and 'speed_rpm' set the same quantity"):
        sweep.SweepConfig(mechanism=mech, grid={"speed": [1.0], "speed_rpm": [60.0], "toy_length:t": [0.4]},
                          ideal_reference=False)


@pytest.mark.extended
def test_the_toy_stiffness_fitted_from_a_record_made_at_a_known_value():
    """A record of the block's acceleration, the closed form ``AMPLITUDE (k / M) cos(sqrt(k/M) t)``
    at k = 800 N/m (0.4 s at 1 kHz) plus white noise of 5 % of its amplitude, fitted from 0.7 k
    with ``free=["toy_stiffness:t"]``. The closed-form Cramer-Rao bound of the stiffness,
    ``sigma / sqrt(sum (da/dk)^2)``, is 1.13 N/m (0.14 %); the estimate must lie within 3 of it
    of the truth, and the fit's own std (Gauss-Newton, with the noise estimated from the residual:
    a relative error about 1/sqrt(2 N) = 3.5 %) within 15 % of it."""
    mech = toy_beside_a_clearance_joint(0.7 * K)
    t = np.arange(400) * 1e-3
    w = np.sqrt(K / M)
    a = AMPLITUDE * w**2 * np.cos(w * t)
    sigma = 0.05 * AMPLITUDE * w**2
    record = {"time_s": t, "acc": a + np.random.default_rng(3).normal(0.0, sigma, t.shape)}
    da_dk = AMPLITUDE / M * np.cos(w * t) - AMPLITUDE * w * t * np.sin(w * t) / (2 * M)  # d omega / dk = omega / 2k
    bound = sigma / np.sqrt(np.sum(da_dk**2))
    with pytest.raises(jc.ParameterError, match=r"start value of 'toy_stiffness:t' is outside its bounds"):
        jc.fit(record, mech, free=["toy_stiffness:t"], start={"toy_stiffness:t": -1.0},
               channels={"acc": "point:block:P:acc:y"})
    res = jc.fit(record, mech, free=["toy_stiffness:t"], channels={"acc": "point:block:P:acc:y"}, window=0.399,
                 progress=False, settings=jc.settings(1.0, rtol=1e-8, atol=1e-11, allow_free_dof=True))
    estimate, std = res.estimates["toy_stiffness:t"], res.std["toy_stiffness:t"]
    assert res.start["toy_stiffness:t"] == pytest.approx(0.7 * K)
    assert abs(estimate - K) < 3 * bound, (estimate, bound)
    assert abs(std / bound - 1) < 0.15, (std, bound)
    assert res.failures == ()
