"""The force elements' own named outputs (Solution.element_outputs, channels joint:K:NAME,
timeseries columns) against what the Solution already reports for the element as one contact
and against the element's geometry written out here: summed corner forces, deepest corner,
the film's share of the joint's normal force, the slot coordinate of the pin."""

from __future__ import annotations

import numpy as np
import pytest

import jaxclear as jc
from jaxclear.analysis import channels
from jaxclear.elements.translational_clearance import CORNERS


@pytest.fixture(scope="module")
def lubricated():
    mech = jc.preset("flores-slider-crank", viscosity=0.4)
    return mech, jc.simulate(mech, jc.settings(2e-3, n_out=41))


@pytest.fixture(scope="module")
def guide():
    mech = jc.preset("slider-crank-guide-clearance", speed_rpm=3000.0)
    return mech, jc.simulate(mech, jc.settings(10e-3, n_out=201))


@pytest.fixture(scope="module")
def slot():
    mech = jc.preset("slider-crank-pin-slot", slot_length=2e-3, speed_rpm=3000.0)
    return mech, jc.simulate(mech, jc.settings(10e-3, n_out=201))


def test_lubricated_joint_outputs(lubricated):
    """Film force: the joint's normal force is the dry force minus the film's normal component,
    so out of contact film_force_normal = -normal_force (1e-9 relative); the global components
    are the n/t components rotated by the line of centres (ecc/|ecc|); the magnitude is their
    norm; the eccentricity ratio is |ecc|/c and the minimum film c - |ecc| (rounding)."""
    mech, sol = lubricated
    out = sol.element_outputs(mech)
    assert list(type(mech.clearance_joints[0]).OUTPUTS) == ["film_force_normal", "film_force_tangential",
                                                            "film_force_x", "film_force_y", "film_force",
                                                            "eccentricity_ratio", "min_film_thickness"]
    c = float(mech.clearance_joints[0].clearance)
    ecc = np.asarray(sol.ecc[:, 0])
    e = np.linalg.norm(ecc, axis=1)
    free = np.asarray(sol.penetration[:, 0]) < 0
    assert free.all() and e[1:].min() > 0  # no dry contact; a line of centres from the first step on
    np.testing.assert_allclose(out["film_force_normal"][free], -np.asarray(sol.normal_force[:, 0])[free],
                               rtol=1e-9, atol=1e-9)
    n = ecc[1:] / e[1:, None]
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    f = np.asarray(out["film_force_normal"])[1:, None] * n + np.asarray(out["film_force_tangential"])[1:, None] * t
    np.testing.assert_allclose(np.stack([out["film_force_x"], out["film_force_y"]], 1)[1:], f, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(out["film_force"], np.hypot(out["film_force_normal"], out["film_force_tangential"]),
                               rtol=1e-12)
    np.testing.assert_allclose(out["eccentricity_ratio"], e / c, rtol=1e-12)
    np.testing.assert_allclose(out["min_film_thickness"], c - e, rtol=1e-12, atol=1e-18)
    values, unit = channels.channel_with_unit(mech, sol, "joint:0:film_force")
    assert unit == "N" and np.array_equal(np.asarray(values), np.asarray(out["film_force"]))
    assert channels.unit(mech, "joint:rod-slider:min_film_thickness") == "m"


def test_translational_joint_outputs_per_corner(guide):
    """Per corner: the summed normal and friction forces are the joint's (1e-9 relative), the
    deepest corner's penetration is the joint's, a corner's mode is 0 exactly when it is out of
    contact; some corner touches in the run."""
    mech, sol = guide
    out = sol.element_outputs(mech)
    fn = np.stack([out[f"{c}_normal_force"] for c in CORNERS], 1)
    ft = np.stack([out[f"{c}_friction_force"] for c in CORNERS], 1)
    pen = np.stack([out[f"{c}_penetration"] for c in CORNERS], 1)
    mode = np.stack([out[f"{c}_mode"] for c in CORNERS], 1)
    assert (fn > 0).any()
    np.testing.assert_allclose(fn.sum(1), sol.normal_force[:, 0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(ft.sum(1), sol.friction_force[:, 0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(pen.max(1), sol.penetration[:, 0], rtol=0, atol=1e-18)
    assert np.array_equal(mode > 0, pen > 0) and set(np.unique(mode)) <= {0, 1, 2}
    assert np.array_equal(np.asarray(sol.mode[:, 0]) > 0, (mode > 0).any(1))
    assert channels.unit(mech, "joint:0:front_upper_penetration") == "m"


def test_pin_slot_outputs_feature_and_its_penetration(slot):
    """The active feature's penetration is the joint's (the law's, to the nearest point of the
    stadium), not |ecc| - c (ecc is the pin centre from the slot centre); the slot coordinate is
    ecc along the slot axis (x here), and the feature is an end exactly where |s| > l/2."""
    mech, sol = slot
    out = sol.element_outputs(mech)
    j = mech.clearance_joints[0]
    np.testing.assert_allclose(out["feature_penetration"], sol.penetration[:, 0], rtol=0, atol=1e-18)
    s = np.asarray(sol.ecc[:, 0, 0])
    np.testing.assert_allclose(out["slot_coordinate"], s, rtol=1e-12, atol=1e-18)
    assert np.array_equal(np.asarray(out["feature"]), (np.abs(s) > 0.5 * float(j.slot_length)).astype(int))
    assert set(np.unique(out["feature"])) == {0, 1}  # both features are visited
    end = np.asarray(out["feature"]) == 1
    naive = np.linalg.norm(np.asarray(sol.ecc[:, 0]), axis=1) - float(j.clearance)
    assert np.abs(naive[end] - np.asarray(out["feature_penetration"])[end]).max() > 0.5e-3  # |ecc| - c misleads


def test_element_outputs_in_the_timeseries_and_bad_names(lubricated):
    mech, sol = lubricated
    df = jc.timeseries_frame(mech, sol)
    assert list(df.columns) == jc.io.timeseries_columns(mech)[1:]
    assert {"film_force_n", "film_force_normal_n", "eccentricity_ratio", "min_film_thickness_m"} <= set(df.columns)
    assert df.attrs["units"]["min_film_thickness_m"] == "m" and df.attrs["units"]["eccentricity_ratio"] == "-"
    with pytest.raises(jc.ParameterError, match="allowed: .*'film_force'"):
        channels.unit(mech, "joint:0:film_pressure")
    dry = jc.preset("flores-slider-crank")
    assert dry.clearance_joints[0].OUTPUTS == {}
    with pytest.raises(jc.ParameterError, match="film_force"):
        channels.unit(dry, "joint:0:film_force")
