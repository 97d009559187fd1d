"""Plain NumPy/SciPy reference for the Flores slider-crank with a revolute clearance joint.

Independent of jax/jaxclear: generalized Cartesian coordinates (Nikravesh), constraint
Jacobian D and the acceleration right-hand side gamma derived by hand, augmented
(index-1, Baumgarte-stabilised) equations of motion solved with ``np.linalg.solve`` and
integrated with ``scipy.integrate.solve_ivp``.

Used as the speed baseline and as an independent truth in the tests.

Coordinates (bodies in index order crank=1, rod=2, slider=3):
    q = [x1, y1, phi1, x2, y2, phi2, x3, y3, phi3]

Clearance model: 7 constraints (ground revolute at the crank, ideal crank-rod revolute,
slider translational joint along ground x, crank driver); the rod-slider revolute has a
clearance and is replaced by a Lankarani-Nikravesh contact force with Ambrosio friction.
Ideal model (``ideal=True``): the rod-slider revolute is an ideal joint (9 constraints,
zero DOF, purely kinematic motion).

The contact-onset approach velocity ``deltadot0`` is history. It is constant between
contact onsets, so instead of carrying it as a 19th state with zero derivative the
integration is done piecewise: ``solve_ivp`` stops at each contact onset (terminal event)
and restarts with ``deltadot0`` set to the penetration velocity at the event.

Event hysteresis: right after an onset restart delta is zero to within root-finding
round-off (it may be -1e-18), and scipy would detect the same "upward crossing" again in
the very first step. So the integration alternates between two kinds of segment:
  * "free"    : wait for contact onset, event delta (direction +1, terminal);
  * "contact" : wait for separation,   event delta + SEP_EPS (direction -1, terminal).
A new impact can only be recorded after the journal has separated by SEP_EPS (1e-12 m,
~2e-9 of the radial clearance), which removes the spurious re-triggering.

The clearance dynamics are chaotic: solutions at different tolerances (or from different
but correct implementations) agree closely only over the first ~1-2 ms (the first few
impacts); after that, compare statistics (peak forces, number of impacts), not traces.

Run ``python benchmarks/scipy_reference.py`` for the 3-revolution benchmark.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.integrate import solve_ivp

# separation depth that re-arms the contact-onset event (see module docstring)
SEP_EPS = 1e-12


# ----------------------------------------------------------------------------------
# parameters
# ----------------------------------------------------------------------------------
def params(**overrides) -> dict:
    """All model numbers (SI units). Keyword arguments override defaults."""
    p = dict(
        r=0.05,  # crank length [m]
        l=0.12,  # connecting-rod length [m]
        m1=0.30, J1=1.0e-4,  # crank
        m2=0.21, J2=2.5e-4,  # rod
        m3=0.14, J3=1.0e-4,  # slider
        g=(0.0, -9.81),  # gravitational acceleration vector, on every body [m/s^2]
        omega=5000.0 * 2.0 * math.pi / 60.0,  # crank speed [rad/s]
        R_B=0.010,  # bearing radius (on slider) [m]
        R_J=0.0095,  # journal radius (on rod) [m]
        E=207e9, nu=0.3,  # Young's modulus [Pa], Poisson ratio (both bodies)
        K=None,  # contact stiffness [N/m^1.5]; None: contact_stiffness's Hertz value
        c_r=0.9,  # coefficient of restitution
        mu=0.0,  # friction coefficient
        v0=1e-4, v1=1e-3,  # Ambrosio friction velocity tolerances [m/s]
        floor=1e-4,  # floor on the onset approach velocity deltadot0 [m/s]
        law="lankarani-nikravesh",  # hysteresis factor chi(c_r): see HYSTERESIS
        alpha=5.0, beta=5.0,  # Baumgarte parameters
    )
    unknown = set(overrides) - set(p)
    if unknown:
        raise KeyError(f"unknown parameter(s): {sorted(unknown)}")
    p.update(overrides)
    return p


#: hysteresis factor chi(c_r) of the dissipative Hertz law F = K d^1.5 (1 + chi ddot / ddot0):
#: Lankarani, Nikravesh, J. Mech. Des. 112 (1990) 369; Flores, Machado, Silva, Martins,
#: Multibody Syst. Dyn. 25 (2011) 357.
HYSTERESIS = {
    "lankarani-nikravesh": lambda c_r: 3.0 * (1.0 - c_r**2) / 4.0,
    "flores": lambda c_r: 8.0 * (1.0 - c_r) / (5.0 * c_r),
}


def contact_stiffness(p) -> float:
    """Lankarani-Nikravesh generalised stiffness K [N/m^1.5] for internal cylinder contact
    (``p["K"]`` instead when that is given)."""
    if p.get("K") is not None:
        return float(p["K"])
    sigma = (1.0 - p["nu"] ** 2) / p["E"]  # same material for bearing and journal
    R_B, R_J = p["R_B"], p["R_J"]
    return (4.0 / 3.0) / (sigma + sigma) * math.sqrt(R_B * R_J / (R_B - R_J))


def mass_matrix(p) -> np.ndarray:
    return np.diag([p["m1"], p["m1"], p["J1"],
                    p["m2"], p["m2"], p["J2"],
                    p["m3"], p["m3"], p["J3"]])


def _body_points(p):
    """Body-fixed points s' (local frame, centroid at origin)."""
    r, l = p["r"], p["l"]
    return dict(
        sO1=np.array([-r / 2, 0.0]),  # crank, ground pivot O
        sA1=np.array([+r / 2, 0.0]),  # crank, crank pin A
        sA2=np.array([-l / 2, 0.0]),  # rod, A
        sB2=np.array([+l / 2, 0.0]),  # rod, B (journal centre)
        sB3=np.array([0.0, 0.0]),  # slider, B (bearing centre)
    )


# ----------------------------------------------------------------------------------
# kinematics helpers
# ----------------------------------------------------------------------------------
def rot(phi):
    """A(phi)."""
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s], [s, c]])


def drot(phi):
    """B(phi) = dA/dphi."""
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[-s, -c], [c, -s]])


def _perp(a):
    return np.array([-a[1], a[0]])


def _cross2(a, b):
    return a[0] * b[1] - a[1] * b[0]


# ----------------------------------------------------------------------------------
# constraints: Phi, D = Phi_q, Phi_t, gamma (all hand-derived)
# ----------------------------------------------------------------------------------
def constraints(q, qd, t, p, ideal=False):
    """Return (Phi, D, Phi_t, gamma) for the clearance (7 eq.) or ideal (9 eq.) model.

    Revolute  r_i + A_i s_i - r_j - A_j s_j = 0:
        D_i = [I, B_i s_i],  D_j = -[I, B_j s_j],
        gamma = A_i s_i phid_i^2 - A_j s_j phid_j^2.
    Ground revolute r_1 + A_1 s_O = 0: D = [I, B_1 s_O], gamma = A_1 s_O phid_1^2.
    Slider y3 = 0, phi3 = 0 and driver phi1 - omega t = 0: linear, gamma = 0,
    Phi_t(driver) = -omega.
    """
    pts = _body_points(p)
    r1, phi1 = q[0:2], q[2]
    r2, phi2 = q[3:5], q[5]
    r3, phi3 = q[6:8], q[8]
    pd1, pd2, pd3 = qd[2], qd[5], qd[8]
    A1, A2, A3 = rot(phi1), rot(phi2), rot(phi3)
    B1, B2, B3 = drot(phi1), drot(phi2), drot(phi3)

    m = 9 if ideal else 7
    Phi = np.zeros(m)
    D = np.zeros((m, 9))
    Phi_t = np.zeros(m)
    gam = np.zeros(m)
    I2 = np.eye(2)

    # 1-2: crank point O at the ground origin
    As = A1 @ pts["sO1"]
    Phi[0:2] = r1 + As
    D[0:2, 0:2] = I2
    D[0:2, 2] = B1 @ pts["sO1"]
    gam[0:2] = As * pd1 ** 2

    # 3-4: crank A = rod A
    As1 = A1 @ pts["sA1"]
    As2 = A2 @ pts["sA2"]
    Phi[2:4] = r1 + As1 - r2 - As2
    D[2:4, 0:2] = I2
    D[2:4, 2] = B1 @ pts["sA1"]
    D[2:4, 3:5] = -I2
    D[2:4, 5] = -(B2 @ pts["sA2"])
    gam[2:4] = As1 * pd1 ** 2 - As2 * pd2 ** 2

    # 5-6: translational joint along the ground x axis
    Phi[4] = q[7]
    D[4, 7] = 1.0
    Phi[5] = phi3
    D[5, 8] = 1.0

    # 7: driver
    Phi[6] = phi1 - p["omega"] * t
    D[6, 2] = 1.0
    Phi_t[6] = -p["omega"]

    if ideal:
        # 8-9: rod B = slider B (ideal revolute)
        As2 = A2 @ pts["sB2"]
        As3 = A3 @ pts["sB3"]
        Phi[7:9] = r2 + As2 - r3 - As3
        D[7:9, 3:5] = I2
        D[7:9, 5] = B2 @ pts["sB2"]
        D[7:9, 6:8] = -I2
        D[7:9, 8] = -(B3 @ pts["sB3"])
        gam[7:9] = As2 * pd2 ** 2 - As3 * pd3 ** 2

    return Phi, D, Phi_t, gam


# ----------------------------------------------------------------------------------
# clearance joint
# ----------------------------------------------------------------------------------
def penetration(q, p):
    """delta = |P_j - P_i| - c (cheap, used by the event functions)."""
    pts = _body_points(p)
    Pi = q[6:8] + rot(q[8]) @ pts["sB3"]  # bearing centre (slider)
    Pj = q[3:5] + rot(q[5]) @ pts["sB2"]  # journal centre (rod)
    e = Pj - Pi
    return math.hypot(e[0], e[1]) - (p["R_B"] - p["R_J"])


def contact(q, qd, p, deltadot0):
    """Clearance-joint kinematics and forces.

    Returns dict: Q (9,) generalised contact force, delta, deltadot, F_N, F_T, v_T, ecc (2,).
    """
    pts = _body_points(p)
    R_B, R_J = p["R_B"], p["R_J"]
    c = R_B - R_J
    r2, phi2, rd2, pd2 = q[3:5], q[5], qd[3:5], qd[5]  # journal body (rod), j
    r3, phi3, rd3, pd3 = q[6:8], q[8], qd[6:8], qd[8]  # bearing body (slider), i

    Pi = r3 + rot(phi3) @ pts["sB3"]
    Pj = r2 + rot(phi2) @ pts["sB2"]
    ecc = Pj - Pi
    e = math.hypot(ecc[0], ecc[1])
    delta = e - c

    out = dict(Q=np.zeros(9), delta=delta, deltadot=0.0, F_N=0.0, F_T=0.0, v_T=0.0, ecc=ecc)
    if e == 0.0:  # journal exactly centred: no direction, certainly no contact
        return out

    n = ecc / e
    t = np.array([-n[1], n[0]])
    vPi = rd3 + pd3 * (drot(phi3) @ pts["sB3"])
    vPj = rd2 + pd2 * (drot(phi2) @ pts["sB2"])
    deltadot = float((vPj - vPi) @ n)
    out["deltadot"] = deltadot

    Qi = Pi + R_B * n  # contact point on the bearing
    Qj = Pj + R_J * n  # contact point on the journal
    vQi = rd3 + pd3 * _perp(Qi - r3)
    vQj = rd2 + pd2 * _perp(Qj - r2)
    v_T = float((vQj - vQi) @ t)
    out["v_T"] = v_T

    if delta <= 0.0:
        return out

    # dissipative Hertz normal force (Lankarani-Nikravesh or Flores hysteresis factor)
    K = contact_stiffness(p)
    dd0 = max(deltadot0, p["floor"])
    F_N = K * delta * math.sqrt(delta) * (1.0 + HYSTERESIS[p["law"]](p["c_r"]) * deltadot / dd0)
    F_N = max(F_N, 0.0)

    # Ambrosio friction
    vt = abs(v_T)
    if vt < p["v0"]:
        c_d = 0.0
    elif vt <= p["v1"]:
        c_d = (vt - p["v0"]) / (p["v1"] - p["v0"])
    else:
        c_d = 1.0
    F_T = -p["mu"] * c_d * F_N * np.sign(v_T)

    f_j = -F_N * n + F_T * t  # on the journal (rod) at Q_j
    f_i = -f_j  # on the bearing (slider) at Q_i
    Q = out["Q"]
    Q[3:5] = f_j
    Q[5] = _cross2(Qj - r2, f_j)
    Q[6:8] = f_i
    Q[8] = _cross2(Qi - r3, f_i)
    out.update(F_N=F_N, F_T=float(F_T))
    return out


# ----------------------------------------------------------------------------------
# equations of motion
# ----------------------------------------------------------------------------------
class Counter:
    """Counts right-hand-side evaluations."""

    def __init__(self):
        self.n = 0

    def reset(self):
        self.n = 0


RHS_COUNTER = Counter()


def _applied_forces(p):
    gx, gy = p["g"]
    return np.array([p["m1"] * gx, p["m1"] * gy, 0.0,
                     p["m2"] * gx, p["m2"] * gy, 0.0,
                     p["m3"] * gx, p["m3"] * gy, 0.0])


def _solve_eom(t, y, p, deltadot0, ideal):
    q, qd = y[:9], y[9:]
    Phi, D, Phi_t, gam = constraints(q, qd, t, p, ideal)
    m = D.shape[0]
    Qa = _applied_forces(p)
    con = None
    if not ideal:
        con = contact(q, qd, p, deltadot0)
        Qa = Qa + con["Q"]
    Phid = D @ qd + Phi_t
    a, b = p["alpha"], p["beta"]
    Aug = np.zeros((9 + m, 9 + m))
    Aug[:9, :9] = mass_matrix(p)
    Aug[:9, 9:] = D.T
    Aug[9:, :9] = D
    rhs_vec = np.concatenate([Qa, gam - 2.0 * a * Phid - b * b * Phi])
    x = np.linalg.solve(Aug, rhs_vec)
    return x[:9], x[9:], con


def rhs(t, y, p, deltadot0=0.0, ideal=False):
    """dy/dt for y = [q(9), qdot(9)] (clearance model unless ideal=True)."""
    RHS_COUNTER.n += 1
    if not np.all(np.isfinite(y)):
        # an over-long trial step of the integrator; NaN makes it reject the step
        return np.full(18, np.nan)
    # such trial steps can also overflow before turning non-finite: no warning spam
    with np.errstate(over="ignore", invalid="ignore"):
        qdd, _, _ = _solve_eom(t, y, p, deltadot0, ideal)
    return np.concatenate([y[9:], qdd])


def outputs(t, y, p, deltadot0=0.0, ideal=False):
    """Diagnostics at one state: qdd, lam, delta, F_N, F_T, ecc (2,)."""
    qdd, lam, con = _solve_eom(t, y, p, deltadot0, ideal)
    if con is None:
        return dict(qdd=qdd, lam=lam, delta=float("nan"), F_N=0.0, F_T=0.0,
                    ecc=np.full(2, np.nan))
    return dict(qdd=qdd, lam=lam, delta=con["delta"], F_N=con["F_N"], F_T=con["F_T"],
                ecc=con["ecc"], deltadot=con["deltadot"], v_T=con["v_T"])


# ----------------------------------------------------------------------------------
# initial conditions
# ----------------------------------------------------------------------------------
def initial_state(p):
    """Crank angle 0 (along +x), journal centred, ideal-kinematics velocities."""
    r, l = p["r"], p["l"]
    q0 = np.array([r / 2, 0.0, 0.0,  # crank
                   r + l / 2, 0.0, 0.0,  # rod
                   r + l, 0.0, 0.0])  # slider (x = r + l)
    _, D, Phi_t, _ = constraints(q0, np.zeros(9), 0.0, p, ideal=True)
    qd0 = np.linalg.solve(D, -Phi_t)
    return q0, qd0


# ----------------------------------------------------------------------------------
# simulation driver
# ----------------------------------------------------------------------------------
def simulate(p, t_end, ts=None, rtol=1e-6, atol=1e-9, method="RK45", ideal=False, start=None):
    """Integrate from t=0 to t_end; results sampled on ts (default 1000 uniform points).

    ``start=(t0, y0, deltadot0)`` continues from the state y0 = [q, qdot] at t0 (the onset
    approach speed deltadot0 of an ongoing contact) instead of ``initial_state`` at t=0.

    Returns dict: t, q (N,9), qdot (N,9), qdd (N,9), slider_acc (N,), delta (N,), F_N (N,),
    deltadot0 (N,) (the onset approach speed the force law used at each output time),
    n_impacts, impact_times (the contact onsets' times), nfev, wall_s (integration wall time,
    excluding output post-processing).
    """
    if start is None:  # start-up (deltadot0 is irrelevant until the first onset)
        t0, y0, deltadot0 = 0.0, np.concatenate(initial_state(p)), p["floor"]
    else:
        t0, y0, deltadot0 = float(start[0]), np.array(start[1], dtype=float), float(start[2])
    ts = np.linspace(t0, t_end, 1000) if ts is None else np.asarray(ts, dtype=float)
    if ts[0] < t0 or ts[-1] > t_end or np.any(np.diff(ts) < 0):
        raise ValueError("ts must be sorted and lie in [t0, t_end]")
    q0 = y0[:9]

    n0 = RHS_COUNTER.n
    wall0 = time.perf_counter()

    Y = np.empty((len(ts), 18))
    DD0 = np.zeros(len(ts))  # deltadot0 valid at each output time
    k = 0  # next output index to fill
    n_impacts = 0
    impact_times = []

    if ideal:
        sol = solve_ivp(lambda t, y: rhs(t, y, p, 0.0, True), (t0, t_end), y0,
                        method=method, t_eval=ts, rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(sol.message)
        Y[:] = sol.y.T
        k = len(ts)
    else:
        in_contact = penetration(q0, p) > 0.0
        while True:  # one solve_ivp call per segment between events, until t_end
            if in_contact:  # wait for separation below -SEP_EPS
                def ev(t, y):
                    return penetration(y[:9], p) + SEP_EPS
                ev.direction = -1
            else:  # wait for contact onset
                def ev(t, y):
                    return penetration(y[:9], p)
                ev.direction = +1
            ev.terminal = True

            dd0 = deltadot0
            sol = solve_ivp(lambda t, y: rhs(t, y, p, dd0), (t0, t_end), y0,
                            method=method, t_eval=ts[k:], rtol=rtol, atol=atol,
                            events=ev)
            if sol.status < 0:
                raise RuntimeError(sol.message)
            nk = len(sol.t)
            if nk:  # (scipy returns y = [] when no output time falls in the segment)
                Y[k:k + nk] = np.asarray(sol.y).T
                DD0[k:k + nk] = dd0
                k += nk
            if sol.status != 1:  # reached t_end
                break
            t0 = float(sol.t_events[0][0])
            y0 = sol.y_events[0][0].copy()
            if t0 >= t_end:
                break
            if in_contact:
                in_contact = False
            else:
                in_contact = True
                n_impacts += 1
                impact_times.append(t0)
                deltadot0 = contact(y0[:9], y0[9:], p, deltadot0)["deltadot"]

    wall_s = time.perf_counter() - wall0
    nfev = RHS_COUNTER.n - n0
    if k != len(ts):
        raise RuntimeError("integration ended before all output times were reached")

    qdd = np.empty((len(ts), 9))
    delta = np.full(len(ts), np.nan)
    F_N = np.zeros(len(ts))
    for i, (t, y) in enumerate(zip(ts, Y)):
        o = outputs(t, y, p, DD0[i], ideal)
        qdd[i] = o["qdd"]
        delta[i] = o["delta"]
        F_N[i] = o["F_N"]

    return dict(t=ts, q=Y[:, :9], qdot=Y[:, 9:], qdd=qdd, slider_acc=qdd[:, 6].copy(), delta=delta,
                F_N=F_N, deltadot0=DD0, n_impacts=n_impacts, impact_times=np.array(impact_times),
                nfev=nfev, wall_s=wall_s)


def exact_slider(p, t):
    """Ideal slider-crank: slider x and its second time derivative (phi = omega t)."""
    r, l, w = p["r"], p["l"], p["omega"]
    phi = w * np.asarray(t)
    s, c = np.sin(phi), np.cos(phi)
    S = l * l - r * r * s * s
    x = r * c + np.sqrt(S)
    d2x = -r * c - r * r * np.cos(2 * phi) / np.sqrt(S) - r ** 4 * s * s * c * c / S ** 1.5
    return x, w * w * d2x


if __name__ == "__main__":
    p = params()
    t_end = 3 * 60.0 / 5000.0
    # fine grid so that max F_N / max delta catch the (short) impact peaks
    res = simulate(p, t_end, ts=np.linspace(0.0, t_end, 20001), rtol=1e-6, atol=1e-9)
    print(f"clearance slider-crank, 3 revolutions (t_end = {t_end:.4f} s), RK45 rtol=1e-6 atol=1e-9")
    print(f"  K          = {contact_stiffness(p):.4e} N/m^1.5")
    print(f"  nfev       = {res['nfev']}")
    print(f"  n_impacts  = {res['n_impacts']}")
    print(f"  wall time  = {res['wall_s']:.2f} s")
    print(f"  max F_N    = {np.max(res['F_N']):.4e} N (on the output grid)")
    print(f"  max delta  = {np.nanmax(res['delta']):.4e} m (on the output grid)")
