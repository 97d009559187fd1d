"""An independent NumPy/SciPy implementation of Simeon's flexible slider-crank (no code shared with
jaxclear): the published reference against which the flexible link is checked.

The model (B. Simeon, "Modelling a flexible slider crank mechanism by a mixed system of DAEs and
PDEs", Math. Modelling of Systems 2 (1996) 1-18; the version of the Test Set for IVP Solvers,
problem "Slider crank", F. Mazzia and F. Iavernaro, University of Bari, contributed by B. Simeon
in 1998, with its reference solution; also in the R package deTestSet): a rigid crank of length
L1 = 0.15 m turned at omega = 150 rad/s from angle 0, an elastic connecting rod of length L2 =
0.30 m (steel, E = 2e11 Pa, square section 8 x 8 mm, density 7870 kg/m^3: mass 0.151104 kg), a
slider of 0.075552 kg; no gravity, no damping.

The rod is a floating frame of reference whose x axis runs from the crank pin A through the
slider pin B; its lateral displacement is two sine modes, w(x) = q1 sin(pi x/L2) + q2
sin(2 pi x/L2) (q1 is the midpoint's distance from the chord AB, positive to the left of A->B),
its axial displacement a quadratic ansatz with nodes at the middle and at B (q3, q4). The
coordinates p = (phi1, phi2, x3) (crank angle, rod angle, slider position) and q = (q1..q4); the
equations of motion

    M(p, q) w = f(p, q, v) - G^T lambda,     G w + gamma(p, q, v) = 0,

with the mass matrix, the quadratic-velocity and stiffness forces and the constraint Jacobian
of the test set's description (loop closure at B including the axial displacement q4 and the
prescribed crank angle phi1 = omega t), written here from those formulas as matrices and solved as
an index-1 system with SciPy's DOP853 at tight tolerances. The test set's reference solution at
t = 0.1 s (MEBDFI, rtol = atol = 1e-14) is :data:`REFERENCE`; :func:`solve` reproduces it (the
check in tests/test_flexible_simeon.py). :func:`geometric_stiffness` adds what the linear model
leaves out and a chain of rigid elements carries: the stiffening of the bending by the rod's
axial force.

The test set's axial mass matrix is rho b h L2 [[8, 1], [1, 2]] (the quadratic bar's is 1/15 of
that); it is kept as published, since the reference solution was computed with it; it changes
only the axial vibration, which the lateral midpoint deflection barely feels.

``python benchmarks/simeon_crank.py`` prints the solution at t = 0.1 s against the reference.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

M1, M2, M3 = 0.36, 0.151104, 0.075552
L1, L2 = 0.15, 0.30
J1, J2 = 0.002727, 0.0045339259
E, B, H, RHO = 0.20e12, 0.0080, 0.0080, 7870.0
OMEGA = 150.0
GRAV = 0.0
#: pi as the test set's model writes it (3.1415927): the reference solution was computed with it,
#: and math.pi moves the solution at t = 0.1 s by 1.8e-7 relative (the stiffness has pi^4).
PI = 3.1415927

#: The test set's consistent start ("ini = 1"): p, q, then their velocities.
START_SMOOTH = np.array([0.0, 0.0, 0.450016933, 0.0, 0.0, 0.103339863e-4, 0.169327969e-4,
                         0.150000000e3, -0.749957670e2, -0.268938672e-5, 0.444896105, 0.463434311e-2,
                         -0.178591076e-5, -0.268938672e-5])
#: The rod straight and unstrained, the rigid mechanism's velocities ("ini = 2").
START_STRAIGHT = np.array([0.0, 0.0, L1 + L2, 0.0, 0.0, 0.0, 0.0, OMEGA, -OMEGA * L1 / L2, 0.0, 0.0, 0.0, 0.0, 0.0])
#: The test set's reference solution at t = 0.1 s from START_SMOOTH: p, q, their velocities.
REFERENCE = np.array([0.1500000000000104e2, -0.3311734988256260, 0.1697373328427860, 0.1893192899613509e-3,
                      0.2375751249879174e-4, -0.5323896770569702e-5, -0.8363313279112129e-5,
                      0.1500000000000000e3, 0.6025346755138369e2, -0.8753116326670527e1, -0.3005541400289738e-1,
                      -0.5500431812571696e-2, 0.4974111734266989e-3, 0.1105560003626645e-2])
T_REFERENCE = 0.1


def _matrices():
    facm, fack, facb = RHO * B * H * L2, E * B * H / L2, B * H * L2
    pi = PI
    mq = facm * np.array([[0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 8.0, 1.0], [0, 0, 1.0, 2.0]])
    kq = fack * np.array([[pi**4 / 24 * (H / L2) ** 2, 0, 0, 0], [0, pi**4 * 2 / 3 * (H / L2) ** 2, 0, 0],
                          [0, 0, 16 / 3, -8 / 3], [0, 0, -8 / 3, 7 / 3]])
    bq = np.zeros((4, 4))
    bq[0, 2], bq[0, 3], bq[1, 3] = -16 / pi**3, 8 / pi**3 - 1 / pi, 0.5 / pi
    bq = facb * (bq - bq.T)
    c1 = facb * np.array([0, 0, 2 / 3, 1 / 6])
    c2 = facb * np.array([2 / pi, 0, 0, 0])
    c12 = L2 * facb * np.array([0, 0, 1 / 3, 1 / 6])
    c21 = L2 * facb * np.array([1 / pi, -0.5 / pi, 0, 0])
    return mq, kq, bq, c1, c2, c12, c21


MQ, KQ, BQ, C1, C2, C12, C21 = _matrices()


_X, _W = np.polynomial.legendre.leggauss(24)
_X, _W = 0.5 * L2 * (_X + 1.0), 0.5 * L2 * _W  # Gauss-Legendre points and weights on [0, L2]
_SLOPES = np.stack([math.pi / L2 * np.cos(math.pi * _X / L2), 2 * math.pi / L2 * np.cos(2 * math.pi * _X / L2)])


def geometric_stiffness(t: float) -> np.ndarray:
    r"""The geometric stiffness (2, 2) of the lateral modes under the rod's axial force, which the
    linear model leaves out: :math:`K^G_{ij} = \int_0^{L_2} N(x)\,\phi_i'\phi_j'\,dx` with
    :math:`\phi_i = \sin(i\pi x/L_2)` and the tension :math:`N(x) = T_B - \rho A \int_x^{L_2}
    a_\parallel\,dx'` from the rigid mechanism's motion at ``t`` (the crank is prescribed): the
    slider's pull :math:`T_B = -m_3\ddot x_3/\cos\varphi_2` and the rod's axial acceleration
    :math:`a_\parallel = a_A\cdot e_\parallel - \dot\varphi_2^2 x` (Gauss-Legendre, 24 points)."""
    th, w = OMEGA * t, OMEGA
    s1, c1_ = math.sin(th), math.cos(th)
    p2 = -math.asin(L1 * s1 / L2)
    s2, c2_ = math.sin(p2), math.cos(p2)
    v2 = -L1 * w * c1_ / (L2 * c2_)
    a2 = (L1 * w * w * s1 + L2 * v2 * v2 * s2) / (L2 * c2_)  # d/dt of L1 w cos th + L2 v2 cos p2 = 0
    ax3 = -L1 * w * w * c1_ - L2 * (a2 * s2 + v2 * v2 * c2_)
    tension_b = -M3 * ax3 / c2_
    a_par = -L1 * w * w * (c1_ * c2_ + s1 * s2)
    area = B * H
    n = tension_b - RHO * area * (a_par * (L2 - _X) - v2 * v2 * (L2**2 - _X**2) / 2)
    return (_SLOPES * (n * _W)) @ _SLOPES.T


def accelerations(t: float, y: np.ndarray, kq=KQ, stiffening: bool = False):
    """``(w, lambda)``: the accelerations (7,) of (p, q) and the 3 multipliers at time ``t`` [s]
    and state ``y`` (14,); ``kq``: the stiffness matrix (``KQ`` scaled to another Young's
    modulus); ``stiffening``: with the lateral modes' :func:`geometric_stiffness`. The test set's
    options of a nonlinear stiffness and of damping are not written here (the reference
    solution is without them)."""
    p1, p2, _ = y[:3]
    q = y[3:7]
    v1, v2 = y[7], y[8]
    qd = y[10:14]
    s12, c12_ = math.sin(p1 - p2), math.cos(p1 - p2)
    s1, c1_, s2, c2_ = math.sin(p1), math.cos(p1), math.sin(p2), math.cos(p2)
    c1q, c2q, c12q = C1 @ q, C2 @ q, C12 @ q
    c1qd, c2qd, c12qd = C1 @ qd, C2 @ qd, C12 @ qd
    mqq = MQ @ q
    m = np.zeros((7, 7))
    m[0, 0] = J1 + M2 * L1 * L1
    m[0, 1] = 0.5 * L1 * L2 * M2 * c12_ + RHO * L1 * (s12 * c2q + c12_ * c1q)
    m[1, 1] = J2 + q @ mqq + 2 * RHO * c12q
    m[2, 2] = M3
    m[0, 3:] = RHO * L1 * (-s12 * C1 + c12_ * C2)
    m[1, 3:] = RHO * C21 + RHO * (BQ.T @ q)
    m[3:, 3:] = MQ
    m = np.triu(m) + np.triu(m, 1).T
    f = np.zeros(7)
    f[0] = (-0.5 * L1 * GRAV * (M1 + 2 * M2) * c1_ - 0.5 * L1 * L2 * M2 * v2 * v2 * s12
            + RHO * L1 * v2 * v2 * (-s12 * c1q + c12_ * c2q) - 2 * RHO * L1 * v2 * (c12_ * c1qd + s12 * c2qd))
    f[1] = (-0.5 * L2 * GRAV * M2 * c2_ + 0.5 * L1 * L2 * M2 * v1 * v1 * s12
            + RHO * L1 * v1 * v1 * (s12 * c1q - c12_ * c2q) - 2 * RHO * v2 * c12qd - 2 * v2 * (qd @ mqq)
            - RHO * (qd @ BQ @ qd) - RHO * GRAV * (c2_ * c1q - s2 * c2q))
    f[3:] = (v2 * v2 * mqq + RHO * (v2 * v2 * C12 + L1 * v1 * v1 * (c12_ * C1 + s12 * C2) + 2 * v2 * (BQ @ qd))
             - RHO * GRAV * (s2 * C1 + c2_ * C2) - kq @ q)
    if stiffening:
        f[3:5] -= geometric_stiffness(t) @ q[:2]
    lq = L2 + q[3]
    g = np.zeros((3, 7))
    g[0, 0], g[0, 1], g[0, 6] = L1 * c1_, lq * c2_, s2
    g[1, 0], g[1, 1], g[1, 2], g[1, 6] = L1 * s1, lq * s2, 1.0, -c2_
    g[2, 0] = 1.0
    qd4 = qd[3]
    gamma = np.array([-L1 * s1 * v1 * v1 - lq * s2 * v2 * v2 + 2 * v2 * c2_ * qd4,
                      L1 * c1_ * v1 * v1 + lq * c2_ * v2 * v2 + 2 * v2 * s2 * qd4, 0.0])
    kkt = np.block([[m, g.T], [g, np.zeros((3, 3))]])
    sol = np.linalg.solve(kkt, np.concatenate([f, -gamma]))
    return sol[:7], sol[7:]


def _rhs(t, y, kq=KQ, stiffening=False):
    return np.concatenate([y[7:], accelerations(t, y, kq, stiffening)[0]])


def constraints(t: float, y: np.ndarray) -> np.ndarray:
    """The position constraints (loop closure at B, the prescribed crank angle) at ``y``: zero on
    the motion [m, m, rad]."""
    p1, p2, x3, q4 = y[0], y[1], y[2], y[6]
    return np.array([L1 * math.sin(p1) + (L2 + q4) * math.sin(p2), x3 - L1 * math.cos(p1) - (L2 + q4) * math.cos(p2),
                     p1 - OMEGA * t])


def solve(t_end: float = T_REFERENCE, start: np.ndarray = START_SMOOTH, times=None, rtol: float = 1e-12,
          atol: float = 1e-14, youngs_modulus: float = E, stiffening: bool = False):
    """The motion from ``start`` (14,) to ``t_end`` [s]: SciPy's ``OdeResult`` (``t``, ``y`` (14,
    n)), sampled at ``times`` where given; ``youngs_modulus`` [Pa] in place of the steel's,
    ``stiffening``: with the lateral modes' :func:`geometric_stiffness` (not in the test set's
    model)."""
    return solve_ivp(_rhs, (0.0, t_end), np.asarray(start, float), method="DOP853", rtol=rtol, atol=atol,
                     t_eval=times, args=(KQ * (youngs_modulus / E), stiffening))


if __name__ == "__main__":
    import time

    t0 = time.perf_counter()
    sol = solve()
    y = sol.y[:, -1]
    names = ["phi1", "phi2", "x3", "q1", "q2", "q3", "q4", "vphi1", "vphi2", "vx3", "vq1", "vq2", "vq3", "vq4"]
    print(f"solved in {time.perf_counter() - t0:.1f} s, {sol.t.size} steps; constraint residual "
          f"{np.max(np.abs(constraints(sol.t[-1], y))):.1e}")
    for n, a, r in zip(names, y, REFERENCE):
        print(f"{n:6s} {a: .12e} {r: .12e} {abs(a - r) / (abs(r) + 1e-300):.1e}")
