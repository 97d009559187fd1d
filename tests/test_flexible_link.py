"""Flexible links of rigid finite elements (``jc.flexible_link``, ``jc.DiscreteBeam``; issue 43)
against truths not from our code: Euler-Bernoulli frequencies of clamped and pinned beams
(Blevins, "Formulas for Natural Frequency and Mode Shape", 1979: beta_n L = 1.87510, 4.69409;
n pi), the model's own closed-form cantilever deflection PL^3/(3EI) (1 - 1/(4 m^2)) (a sum
written by hand in jaxclear/model/discrete_beam.py's docstring), energy balance of a free
flexible pendulum, and derivatives against central differences of tight runs."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxclear as jc
from jaxclear.analysis.channels import channel

L, E, RHO, D = 0.5, 2.1e11, 7800.0, 0.01  # m, Pa, kg/m^3, m: a steel rod of 10 mm
AREA, SECOND = np.pi * D**2 / 4, np.pi * D**4 / 64
MU = RHO * AREA
MASS = MU * L
TIGHT = dict(rtol=1e-10, atol=1e-13)


def beam(support: str, gravity=(0.0, 0.0), load=None) -> jc.Mechanism:
    """A rigid bar from ground point o along +x: clamped at o, pinned at o with a roller at its
    other end, or hanging from a pin at o (``"pendulum"``); ``load`` [N]: a point force at the tip."""
    body = jc.Body("beam", MASS, MASS * L**2 / 12, {"a": (-L / 2, 0.0), "b": (L / 2, 0.0)}, position=(L / 2, 0.0, 0.0))
    if support == "clamped":
        joints = [jc.Fixed(jc.GROUND, "o", "beam", "a")]
    elif support == "pinned":
        joints = [jc.Revolute(jc.GROUND, "o", "beam", "a"), jc.PointOnLine(jc.GROUND, "e", "beam", "b")]
    else:
        joints = [jc.Revolute(jc.GROUND, "o", "beam", "a")]
    loads = [] if load is None else [jc.PointForce("beam", "b", load)]
    return jc.Mechanism([body], joints, loads=loads, gravity=gravity, ground_points={"o": (0.0, 0.0), "e": (L, 0.0)},
                        name=f"{support}-beam")


def linearized(mech: jc.Mechanism):
    """The start state and the Jacobian of the accelerations with respect to (q, qdot) there."""
    start = jc.initial_state(mech, jc.settings(1.0, allow_free_dof=True))
    n = start.q.shape[0]
    gains = jc.Baumgarte(jnp.asarray(5.0), jnp.asarray(5.0))

    @jax.jit
    def jacobian(x):
        return jax.jacfwd(lambda y: jc.accelerations(mech, 0.0, y[:n], y[n:], (), gains)[0])(x)

    x = jnp.concatenate([start.q, start.qdot])
    return start, np.asarray(jacobian(x)), n


def frequencies(mech: jc.Mechanism) -> np.ndarray:
    """The undamped natural frequencies [rad/s]: the eigenvalues i omega of the linearized state
    equations (the constraints' Baumgarte directions give real eigenvalues, -5 twice, left out)."""
    _, jac, n = linearized(mech)
    ev = np.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)], [jac]]))
    oscillating = ev[(np.abs(ev.imag) > 1e-3) & (np.abs(ev.real) < 1e-6 * np.abs(ev.imag))]
    return np.unique(np.round(np.abs(oscillating.imag), 6))


@pytest.mark.parametrize("support, beta, order", [("clamped", (1.87510407, 4.69409113), 2.0),
                                                  ("pinned", (np.pi, 2 * np.pi), 4.0)])
@pytest.mark.extended
def test_natural_frequencies_converge_to_euler_bernoulli(support, beta, order):
    """First two bending frequencies with 4 and 8 elements against Euler-Bernoulli's
    (beta_n L)^2 sqrt(EI / (mu L^4)). Measured (2026-11-30): clamped 1.45e-2, 5.2e-2 (4
    elements), 3.6e-3, 1.26e-2 (8): second order; pinned -3.05e-4, -7.3e-3 (4), -1.7e-5, -3.05e-4
    (8): fourth order (the half elements at the pins make the secondary division symmetric).
    Asserted: the error falls by 2^order within 25 % and is below 1.5 % (first mode, 4 elements)."""
    exact = np.asarray(beta) ** 2 * np.sqrt(E * SECOND / (MU * L**4))
    errors = []
    for m in (4, 8):
        link = jc.flexible_link(beam(support), "beam", youngs_modulus=E, second_moment=SECOND, elements=m)
        errors.append(np.abs(frequencies(link)[:2] / exact - 1.0))
    assert errors[0][0] < 0.015
    ratio = errors[0] / errors[1]
    np.testing.assert_allclose(np.log2(ratio), order, atol=0.25 * order)


def test_cantilever_tip_deflection_is_the_models_closed_form():
    """A tip load P = 0.1 N (deflection ~ 2e-5 L: geometric nonlinearity ~ 1e-10 relative): one
    Newton step on the linearized accelerations gives the static tip deflection, which the rigid
    finite element model has in closed form, PL^3/(3EI) (1 - 1/(4 m^2)) (a midpoint sum), to
    1e-7 relative (the step's own error is the nonlinearity's); Euler-Bernoulli's PL^3/(3EI) to
    1/(4 m^2) = 1.6 %."""
    m, p = 4, 0.1
    link = jc.flexible_link(beam("clamped", load=(0.0, -p)), "beam", youngs_modulus=E, second_moment=SECOND,
                            elements=m)
    start, jac, n = linearized(link)
    qdd = jc.accelerations(link, 0.0, start.q, start.qdot, (), jc.Baumgarte(jnp.asarray(5.0), jnp.asarray(5.0)))[0]
    q = np.asarray(start.q) - np.linalg.solve(jac[:, :n], np.asarray(qdd))
    tip = float(link.point_position(jnp.asarray(q), "beam_4", "b")[1])
    closed = p * L**3 / (3 * E * SECOND) * (1 - 1 / (4 * m**2))
    assert -tip == pytest.approx(closed, rel=1e-7)
    assert -tip == pytest.approx(p * L**3 / (3 * E * SECOND), rel=1 / (4 * m**2) + 1e-6)
    # the outputs at the nodes: the bending moment is statics', P (L - s_k), s_k = (k - 1/2) L / m
    # (to the nonlinearity's 1e-9); the nodes' deflections from the chord are the link's shape
    out = link.loads[-1].outputs(link, 0.0, jnp.asarray(q), start.qdot)
    s_k = (np.arange(1, m + 1) - 0.5) * L / m
    moments = np.array([float(out[f"moment_{k}"]) for k in range(1, m + 1)])
    np.testing.assert_allclose(np.abs(moments), p * (L - s_k), rtol=1e-6)
    shape = np.array([float(out[f"deflection_{k}"]) for k in range(1, m + 1)])
    assert np.all(shape > 0.0) and shape[1] > shape[0] and shape[2] > shape[3]  # above the chord, most inside
    assert set(link.loads[-1].OUTPUTS) >= {"deflection", "moment_max", f"moment_{m}", f"deflection_{m}"}


def test_free_flexible_pendulum_keeps_its_energy_and_loses_what_its_damping_dissipates():
    """A soft link (E / 1000) released horizontal under gravity, 0.2 s at rtol 1e-10: kinetic +
    potential + strain energy constant to 1e-9 of the energy exchanged (the integration's error);
    with Kelvin-Voigt damping eta = 2e-3 s (zeta = eta omega / 2 = 2.5 % in the first bending
    mode, about 25 rad/s), the bodies' kinetic + potential energy changes by the work of the
    link's sdes (the integral of their power, elastic and dissipative: trapezoids on 4001
    samples, to 1e-4 of the energy exchanged), and the total falls by the dissipated work."""
    s = jc.settings(0.2, n_out=4001, allow_free_dof=True, **TIGHT)
    exchanged = MASS * 9.81 * L / 2
    for eta in (0.0, 2e-3):
        link = jc.flexible_link(beam("pendulum", gravity=(0.0, -9.81)), "beam", youngs_modulus=E / 1000,
                                second_moment=SECOND, elements=4, damping=eta)
        sol = jc.simulate(link, s)
        bodies = np.asarray(jax.vmap(lambda q, qd: jc.energy(link, q, qd))(sol.q, sol.qdot))
        total = bodies + np.asarray(channel(link, sol, "load:beam:energy"))
        deflection = np.asarray(channel(link, sol, "load:beam:deflection"))
        assert np.abs(deflection).max() > 1e-4  # the link bends (so the strain energy is in the balance)
        if eta == 0.0:
            assert np.abs(total - total[0]).max() < 1e-9 * exchanged
            continue
        power = np.asarray(channel(link, sol, "load:beam:power"))
        work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(np.asarray(sol.ts)))])
        np.testing.assert_allclose(bodies - bodies[0], work, atol=1e-4 * exchanged)
        assert total[0] - total[-1] > 1e-3 * exchanged
        assert np.all(np.diff(total) < 1e-9 * exchanged)  # dissipation only takes energy out


@pytest.mark.extended
def test_derivative_with_respect_to_the_modulus_against_central_differences():
    """d(tip height at 50 ms)/dE of the soft pendulum by the error-controlled sensitivities
    against central differences of runs at rtol 1e-10, over a step sweep h/E = 1e-2 .. 1e-5 that
    shows its plateau (truncation falls as h^2, the runs' error 1e-12 m over a difference of
    h dE grows as 1/h): to 1e-5 relative at the plateau's best step."""
    link = jc.flexible_link(beam("pendulum", gravity=(0.0, -9.81)), "beam", youngs_modulus=E / 1000,
                            second_moment=SECOND, elements=4)
    s = jc.settings(0.05, n_out=2, allow_free_dof=True, **TIGHT)

    def tip(sol, mech):
        return mech.point_position(sol.q[-1], "beam_4", "b")[1]

    _, d = jc.sensitivities(link, ["beam_modulus:beam"], s, output=tip)
    e0 = jc.params.get(link, "beam_modulus:beam")
    steps = [1e-2, 1e-3, 1e-4, 1e-5]
    fd = []
    for h in steps:
        up, down = (jc.params.replace(link, "beam_modulus:beam", e0 * (1 + sign * h)) for sign in (1, -1))
        fd.append((float(tip(jc.simulate(up, s), up)) - float(tip(jc.simulate(down, s), down))) / (2 * h * e0))
    errors = np.abs(np.asarray(fd) / float(d["beam_modulus:beam"]) - 1.0)
    assert errors[0] > errors[1] > errors[2]  # truncation falling as h^2 into the plateau
    assert errors.min() < 1e-5


def test_joints_and_roles_move_to_the_elements_that_hold_their_points():
    """The preset slider-crank's rod made flexible: the crank pin and the clearance joint's
    journal on the end elements, the role on the middle one; body-only references refused."""
    mech = jc.preset("flores-slider-crank")
    link = jc.flexible_link(mech, "rod", youngs_modulus=207e9, second_moment=4e-9, elements=4)
    assert [b.name for b in link.bodies] == ["crank", "rod_0", "rod_1", "rod_2", "rod_3", "rod_4", "slider"]
    assert link.role("rod") == "rod_2"
    assert link.clearance_joints[0].journal_body == "rod_4"
    assert sum(float(b.mass) for b in link.bodies if b.name.startswith("rod_")) == pytest.approx(0.21, rel=1e-14)
    assert link.n_constraints == mech.n_constraints + 2 * 4  # the elements pinned at the nodes
    driven = eqx.tree_at(lambda m: m.drivers, mech, (jc.AngleDriver("rod", 1.0),))
    with pytest.raises(jc.MechanismError, match="refers to body 'rod' by its 'body' alone"):
        jc.flexible_link(driven, "rod", youngs_modulus=207e9, second_moment=4e-9)
    with pytest.raises(jc.ParameterError, match="elements"):
        jc.flexible_link(mech, "rod", youngs_modulus=207e9, second_moment=4e-9, elements=0)
    with pytest.raises(jc.ParameterError, match="youngs_modulus"):
        jc.flexible_link(mech, "rod", youngs_modulus=-1.0, second_moment=4e-9)
    assert "beam_modulus:rod" in jc.differentiable_names(link)
    named = eqx.tree_at(lambda m: m.bodies[1].points, mech, {**mech.bodies[1].points, "middle": jnp.zeros(2)})
    with pytest.raises(jc.MechanismError, match=r"points named \['middle'\]"):
        jc.flexible_link(named, "rod", youngs_modulus=207e9, second_moment=4e-9)


def test_axial_and_shear_springs_give_the_pinned_link_its_timoshenko_correction():
    """``axial="elastic"``: the elements joined by axial (EA/Delta), shear (kappa G A/Delta) and
    bending springs instead of pins. The pinned beam's first bending frequency is the
    inextensible link's lowered by shear, which Timoshenko's beam puts at a relative
    (1/2) (n pi r/L)^2 (1 + E/(kappa G)) for the first mode (r^2 = I/A; Timoshenko, Phil. Mag. 41
    (1921) 744; the rotary inertia's share, (1/2)(n pi r/L)^2, is not modelled: the elements'
    inertia is the bar's, not the section's): here 3.56e-4 (measured 3.55e-4 with 4 elements).
    Asserted: the elastic link's first frequency below the pinned one's by that within 5 %."""
    g, kappa = E / (2 * 1.3), 0.9
    support = beam("pinned")
    pinned = frequencies(jc.flexible_link(support, "beam", youngs_modulus=E, second_moment=SECOND, elements=4))[0]
    elastic = frequencies(jc.flexible_link(support, "beam", youngs_modulus=E, second_moment=SECOND, elements=4,
                                           axial="elastic", area=AREA, shear_modulus=g, shear_factor=kappa))[0]
    shear = 0.5 * (np.pi / L) ** 2 * SECOND / AREA * E / (kappa * g)
    assert 1 - elastic / pinned == pytest.approx(shear, rel=0.05)


def test_a_flexible_mechanism_is_saved_and_read_back_leaf_by_leaf(tmp_path):
    """Mechanism files hold the link: its elements as bodies, the pins as joints, the sdes as a
    ``discrete-beam`` load; read back equal leaf by leaf; a broken end pair is named."""
    link = jc.flexible_link(jc.preset("flores-slider-crank"), "rod", youngs_modulus=207e9, second_moment=4e-9,
                            elements=3, damping=1e-6, axial="elastic", area=2e-4, shear_modulus=8e10)
    path = tmp_path / "flexible.toml"
    jc.save_mechanism(link, path)
    assert eqx.tree_equal(jc.load_mechanism(path), link)
    text = path.read_text()
    assert "start" not in text  # a straight start is the default, not written
    start = text.index("end_b = [")
    path.write_text(text[:start] + 'end_b = ["rod_3"]\n' + text[text.index("]", start) + 2:])
    with pytest.raises(jc.ParameterError, match=r"loads\[0\].*end_b must be a \(body, point\) pair"):
        jc.load_mechanism(path)


def test_a_link_started_bent_in_its_first_mode_vibrates_at_its_frequency(tmp_path):
    """``jc.bent_link``: the pinned beam (4 elements) started in its first mode's shape
    A sin(pi s / L), A = 1e-4 m, at rest, and once straight with the rate A omega_1 sin(pi s / L).
    Truths: each rigid element is the chord of the sine between its ends, so the middle's
    deflection at the start is A cos(pi / (2 m)) (the middle element spans (m/2 -+ 1/2) Delta;
    measured 1.3e-7 relative off: the geometric nonlinearity of a deflection of 2e-4 L); the
    deflection then follows d0 cos(omega_1 t), and from the straight start A cos(pi / (2 m))
    sin(omega_1 t), with omega_1 Euler-Bernoulli's pi^2 sqrt(EI / (mu L^4)) (the model's own
    first frequency is 3.05e-4 below it with 4 elements, 6e-3 of a radian over two periods).
    Bounds: the start within 1e-5, the motion within 1e-2 A over two periods (measured with 8
    elements: 1.9e-4 and 3e-8; the sampled sine excites the higher modes a little). A straight
    shape is no bending; a bent start (of the benchmark's rod) is saved to a mechanism file and
    read back; a link name
    that does not exist and a shape that is not finite are refused."""
    m, amplitude = 4, 1e-4
    link = jc.flexible_link(beam("pinned"), "beam", youngs_modulus=E, second_moment=SECOND, elements=m)
    omega = np.pi**2 * np.sqrt(E * SECOND / (MU * L**4))
    shape = lambda s: amplitude * np.sin(np.pi * s / L)  # noqa: E731
    expected0 = amplitude * np.cos(np.pi / (2 * m))
    t_end = 2 * 2 * np.pi / omega
    s = jc.settings(t_end=t_end, n_out=161, rtol=1e-9, atol=1e-13, allow_free_dof=True)
    bent = jc.bent_link(link, "beam", shape)
    sol = jc.simulate(bent, s)
    t, d = np.asarray(sol.ts), np.asarray(channel(bent, sol, "load:beam:deflection"))
    assert d[0] == pytest.approx(expected0, rel=1e-5)
    assert np.max(np.abs(d - d[0] * np.cos(omega * t))) < 1e-2 * amplitude
    moving = jc.bent_link(link, "beam", lambda s: 0.0, lambda s: omega * shape(s))
    sol = jc.simulate(moving, s)
    d = np.asarray(channel(moving, sol, "load:beam:deflection"))
    assert abs(d[0]) < 1e-12
    assert np.max(np.abs(d - expected0 * np.sin(omega * t))) < 1e-2 * amplitude
    straight = jc.bent_link(link, "beam", lambda s: 0.3 * s)
    assert np.max(np.abs(np.asarray(straight.loads[-1].start))) < 1e-15  # rounding of the slopes' differences
    rod = jc.bent_link(jc.flexible_link(jc.preset("flores-slider-crank"), "rod", youngs_modulus=207e9,
                                        second_moment=4e-9, elements=3), "rod", shape, lambda s: omega * shape(s))
    path = tmp_path / "bent.toml"  # (the benchmark's rod: a bent link beside a clearance joint)
    jc.save_mechanism(rod, path)
    assert eqx.tree_equal(jc.load_mechanism(path), rod)
    assert np.all(np.asarray(rod.loads[-1].start) < 0.0)  # a bump to the left: its slope falls at every node
    assert np.all(np.asarray(rod.loads[-1].start_rate) < 0.0)
    with pytest.raises(jc.MechanismError, match=r"bent_link: no flexible link named 'rod'; this mechanism's: \['beam'\]"):
        jc.bent_link(link, "rod", shape)
    with pytest.raises(jc.ParameterError, match="the start's deflection is not finite"):
        jc.bent_link(link, "beam", lambda s: np.nan)


def spun_blade(elements: int):
    """Kane, Ryan and Banerjee's (1987) spin-up as a mechanism: a hub turned about the ground
    point o by the prescribed angle of :class:`jaxclear.flexible.supports.SpinUp` (Omega_s = 6
    rad/s over T_s = 15 s), the blade (L = 8 m aluminium, first frequency 2.91 rad/s) welded to
    it at its end a and made a flexible link of ``elements`` rigid finite elements."""
    from jaxclear.flexible.supports import SpinUp

    spin = SpinUp(6.0, 15.0)
    length, rho_a = 8.0, 2766.67 * 7.2968e-5
    mass = rho_a * length
    hub = jc.Body("hub", 1.0, 0.1, {"o": (0.0, 0.0)})
    blade = jc.Body("blade", mass, mass * length**2 / 12, {"a": (-length / 2, 0.0), "b": (length / 2, 0.0)},
                    position=(length / 2, 0.0, 0.0))
    mech = jc.Mechanism([hub, blade], [jc.Revolute(jc.GROUND, "o", "hub", "o"),
                                       jc.FunctionDriver("hub", "phi", lambda t: spin(t)),
                                       jc.Fixed("hub", "o", "blade", "a")],
                        gravity=(0.0, 0.0), ground_points={"o": (0.0, 0.0)}, name="spin-up")
    return jc.flexible_link(mech, "blade", youngs_modulus=6.895e10, second_moment=8.2189e-9, elements=elements), spin


def test_spun_up_link_stays_bounded_with_the_stiffened_floating_frame_model():
    """Geometric stiffening in a mechanism: Kane, Ryan and Banerjee's spin-up (``spun_blade``)
    with the link of 8 rigid finite elements, 20 s at rtol 1e-6. The linear floating-frame model
    without the centrifugal stiffening (SciPy, ``tests/test_flexible.modal_spinup``: no code of
    ours) passes 1e3 m of tip deflection by 10 s and 1e20 m by 20 s; the link's tip deflection
    in the rotating frame stays bounded and follows the one-mode model with the stiffening term
    (largest 0.758 m): measured 2026-12-02, largest difference 9.1 %, 2.65 %, 1.36 % of 0.758 m
    with 4, 8, 16 elements (second order, the clamped link's, down to the one-mode reference's
    own error), 0.74 m largest, within 8 mm after the spin-up. Asserted with 8: within 3.5 % of
    the largest stiffened deflection, within 1 cm after 16 s. The stiffening comes from the
    joints' reactions alone (the elements turn rigidly): no term of ours adds it."""
    from test_flexible import modal_spinup

    link, spin = spun_blade(8)
    sol = jc.simulate(link, jc.settings(20.0, n_out=201, rtol=1e-6, atol=1e-8, max_steps=1_000_000))
    assert sol.ok
    t = np.asarray(sol.ts)
    tip = np.asarray(jax.vmap(lambda q: link.point_position(q, "blade_8", "b"))(sol.q))
    theta = np.asarray(jax.vmap(spin)(sol.ts))
    v = -np.sin(theta) * tip[:, 0] + np.cos(theta) * tip[:, 1]
    linear = modal_spinup(8.0, 6.895e10 * 8.2189e-9, 2766.67 * 7.2968e-5, 6.0, 15.0, 20.0, stiffening=False)(t)
    stiffened = modal_spinup(8.0, 6.895e10 * 8.2189e-9, 2766.67 * 7.2968e-5, 6.0, 15.0, 20.0, stiffening=True)(t)
    assert abs(linear[100]) > 1e3 and abs(linear[-1]) > 1e20
    assert np.abs(v).max() < 1.0 and np.abs(v[t >= 16.0]).max() < 1e-2
    assert np.abs(v - stiffened).max() < 0.035 * np.abs(stiffened).max()


@pytest.mark.slow
def test_large_tip_deflection_converges_to_the_elastica_at_second_order():
    """The cantilever (the 0.5 m steel rod clamped at o) under a vertical dead tip load
    P = alpha EI / L^2, alpha = 1, 2, 5, 10 (tip rotation up to 82 degrees), the link of 8 and 16
    rigid finite elements: the static state by Newton's method on the accelerations at rest
    (load steps of alpha / 20, 12 iterations each) against Mattiasson's table of the elastica
    (``tests/test_flexible.MATTIASSON``, checked there against our quadrature of the elliptic
    integrals). Large rotations are exact in this model (each element turns rigidly), so the
    error is the discretisation's alone: measured 2026-12-02 in v/L at alpha = 10, 2.57e-2,
    6.27e-3, 1.55e-3 with 4, 8, 16 elements (second order: ratios 4.10, 4.05), and Richardson's
    extrapolation of 8 and 16 within 2e-5 of the table. Asserted: the ratio of v's errors 4 within
    10 % at every alpha (u's, 3e-6 to 3.5e-4 with 16 elements, reach the table's five digits),
    the extrapolation of both within 1e-4 L."""
    from test_flexible import MATTIASSON

    gains = jc.Baumgarte(jnp.asarray(5.0), jnp.asarray(5.0))
    tips = {}
    for m in (8, 16):
        link = jc.flexible_link(beam("clamped", load=(0.0, -1.0)), "beam", youngs_modulus=E, second_moment=SECOND,
                                elements=m)
        start = jc.initial_state(link, jc.settings(1.0, allow_free_dof=True))

        def at_rest(q, p, link=link, qdot=start.qdot):
            loaded = eqx.tree_at(lambda mech: mech.loads[0].force, link, jnp.stack([0.0 * p, -p]))
            return jc.accelerations(loaded, 0.0, q, qdot, (), gains)[0]

        newton = jax.jit(lambda q, p, f=at_rest: q - jnp.linalg.solve(jax.jacfwd(f)(q, p), f(q, p)))
        q = start.q
        for alpha in np.linspace(0.5, 10.0, 20):
            p = alpha * E * SECOND / L**2
            for _ in range(12):
                q = newton(q, p)
            if float(alpha) in MATTIASSON:
                # converged: to 1e-6 of the load's acceleration of one element (rounding: 1e-7)
                assert float(jnp.abs(at_rest(q, p)).max()) < 1e-6 * p * m / MASS
                x, y = np.asarray(link.point_position(q, f"beam_{m}", "b"))
                tips[m, float(alpha)] = np.array([(L - x) / L, -y / L])
    for alpha, table in MATTIASSON.items():
        e8, e16 = tips[8, alpha] - table, tips[16, alpha] - table
        np.testing.assert_allclose(e8[1] / e16[1], 4.0, rtol=0.1)  # v (u's errors reach the table's digits)
        np.testing.assert_allclose(tips[16, alpha] + (tips[16, alpha] - tips[8, alpha]) / 3, table, atol=1e-4)


def test_the_implicit_solver_runs_a_mechanism_to_its_tolerance():
    """``solver="kvaerno5"`` (diffrax's implicit ESDIRK) on the flexible pendulum of 2 elements:
    its Newton iterations take the run's tolerances and error norm (diffrax fills them in only
    for its own step-size controller; through jaxclear's wrappers the run stopped with an
    AttributeError). Against a run at rtol 1e-11: within 1e-5 m at rtol 1e-6 (measured 4.3e-7;
    Tsit5 2.7e-8). Its cost on this model (136 steps against Tsit5's 23, 28 s of compilation) and
    on the flexible slider-crank (docs/theory/flexible-links.md) is why it is not the default."""
    link = jc.flexible_link(beam("pendulum", gravity=(0.0, -9.81)), "beam", youngs_modulus=E / 1000,
                            second_moment=SECOND, elements=2)
    ref = jc.simulate(link, jc.settings(0.1, n_out=11, allow_free_dof=True, rtol=1e-11, atol=1e-14))
    sol = jc.simulate(link, jc.settings(0.1, n_out=11, allow_free_dof=True, solver="kvaerno5", rtol=1e-6, atol=1e-9))
    assert np.abs(np.asarray(sol.q) - np.asarray(ref.q)).max() < 1e-5
    assert np.abs(np.asarray(sol.q) - np.asarray(ref.q)[0]).max() > 1e-2  # it moved
