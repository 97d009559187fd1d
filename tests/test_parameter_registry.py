"""One parameter registry (issue 40, item 4): every class declares its named parameters next to
its fields (``PARAMETERS``), :mod:`jaxclear.params` composes them, and a new force element is one
class in one file. The toy element here is defined in this file only and registered nowhere
(not in the mechanism files' ``CONNECTORS``): names, values, ranges (eager and inside ``jit``),
the differentiable names, ``jax.grad`` of a run, the structure check and the drawing all find it
through its declaration."""

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
    (1.2e-8, 4.2e-9, 2.0e-8 at 1e-4, 1e-5, 1e-6, where the runs' errors, about 1e-13 m over a
    difference of 2 h |dy/dk|, take over: 2.7e-8 at 1e-7). The gradient is the plateau's value."""
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
    plateau = [errors[r] for r in (1e-4, 1e-5, 1e-6, 1e-7)]
    assert max(plateau) < 5e-8 and min(plateau) < 1e-8  # the plateau, where the gradient lies


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
    catalogue composed from the registered classes is the one ``INFO`` lists (45 names)."""
    for cls, *_ in LAWS.values():
        assert cls.PARAMETERS["stiffness"].field == cls.stiffness_parameter, cls
    assert len(params.INFO) == 45 and params.parameter_names() == sorted(params.INFO)
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
