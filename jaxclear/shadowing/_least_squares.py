r"""The small least-squares problem of NILSS: the coefficients of the homogeneous tangents on
every segment.

On segment :math:`i` (of :math:`K`) the tangent is :math:`v_i = v^*_i + W_i a_i`, with
:math:`a_i \in \mathbb R^{n_u}` (one column per parameter). The coefficients minimise the
time integral of the tangent's part normal to the flow,

.. math::

    \min_{a_0..a_{K-1}} \sum_i \tfrac12 a_i^\top C_i a_i + d_i^\top a_i, \qquad
    C_i = \int W_i^{\perp\top} W_i^\perp \,dt, \quad d_i = \int W_i^{\perp\top} v_i^{*\perp}\,dt,

subject to the continuity of the tangent across every segment boundary, which after the
renormalisation :math:`W_i^\perp(t_{i+1}) = Q_{i+1} R_i`,
:math:`b_i = Q_{i+1}^\top v_i^{*\perp}(t_{i+1})` reads :math:`a_{i+1} = R_i a_i + b_i`
(:math:`i = 0..K-2`). The KKT system

.. math::

    \begin{pmatrix} C & B^\top \\ B & 0 \end{pmatrix}
    \begin{pmatrix} a \\ \lambda \end{pmatrix} =
    \begin{pmatrix} -d \\ b \end{pmatrix},

:math:`C` block diagonal and :math:`B` block bidiagonal (:math:`-R_i` and :math:`I`), is solved
through its Schur complement :math:`S = B C^{-1} B^\top` (Ni and Wang 2017, and the
FD-NILSS paper of Ni, Wang, Fernandez and Talnikar, J. Comput. Phys. 394 (2019) 615-631):
:math:`S \lambda = -(b + B C^{-1} d)`, :math:`a = -C^{-1}(d + B^\top \lambda)`. :math:`S` is
symmetric positive definite and block tridiagonal with blocks of size :math:`n_u`, so it is
factorised block by block in two ``lax.scan`` passes (block :math:`LDL^\top`, Thomas'
algorithm): :math:`O(K n_u^3)` work and :math:`O(K n_u^2)` memory, where a dense factorisation of
the :math:`(K-1) n_u` square matrix would hold :math:`K^2 n_u^2` numbers. :func:`kkt_dense` is the dense reference.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def _block_tridiagonal_solve(diag, upper, rhs):
    r"""Solve :math:`S x = r` for a symmetric positive definite block-tridiagonal :math:`S`.

    ``diag``: ``(m, n, n)`` diagonal blocks; ``upper``: ``(m - 1, n, n)`` blocks
    :math:`S_{i,i+1}` (:math:`S_{i+1,i}` is their transpose); ``rhs``: ``(m, n, p)``.
    Returns ``(m, n, p)``."""
    m = diag.shape[0]
    if m == 1:
        return jnp.linalg.solve(diag[0], rhs[0])[None]
    lower = jnp.swapaxes(upper, -1, -2)  # S_{i+1,i}

    def forward(carry, xs):
        d_prev, y_prev = carry
        a_i, l_i, r_i = xs
        factor = jnp.linalg.solve(d_prev.T, l_i.T).T  # S_{i,i-1} D_{i-1}^{-1}
        d_i = a_i - factor @ jnp.swapaxes(l_i, -1, -2)
        y_i = r_i - factor @ y_prev
        return (d_i, y_i), (d_i, y_i)

    _, (d_rest, y_rest) = jax.lax.scan(forward, (diag[0], rhs[0]), (diag[1:], lower, rhs[1:]))
    d_all = jnp.concatenate([diag[:1], d_rest])
    y_all = jnp.concatenate([rhs[:1], y_rest])
    x_last = jnp.linalg.solve(d_all[-1], y_all[-1])

    def backward(x_next, xs):
        d_i, y_i, e_i = xs
        x_i = jnp.linalg.solve(d_i, y_i - e_i @ x_next)
        return x_i, x_i

    _, x_rest = jax.lax.scan(backward, x_last, (d_all[:-1], y_all[:-1], upper), reverse=True)
    return jnp.concatenate([x_rest, x_last[None]])


@jax.jit
def shadowing_coefficients(C, d, R, b):
    r"""The coefficients :math:`a_i` of the homogeneous tangents (the KKT solution).

    Args:
        C: ``(K, n_u, n_u)``, :math:`\int W_i^{\perp\top}W_i^\perp dt` of every segment.
        d: ``(K, n_u, p)``, :math:`\int W_i^{\perp\top}v_i^{*\perp} dt`, one column per parameter.
        R: ``(K - 1, n_u, n_u)``, the triangular factor of the renormalisation at the end of
            segments ``0..K-2``.
        b: ``(K - 1, n_u, p)``, the inhomogeneous tangent's components on the new basis there.

    Returns:
        ``(K, n_u, p)``: :math:`a_i`, so that :math:`v_i = v^*_i + W_i a_i`.
    """
    K, n_u = C.shape[0], C.shape[1]
    p = d.shape[-1]
    if n_u == 0:
        return jnp.zeros((K, 0, p), d.dtype)
    c_inv = jnp.linalg.inv(C)
    r_t = jnp.swapaxes(R, -1, -2)
    # S = B C^-1 B^T: diagonal R_i C_i^-1 R_i^T + C_{i+1}^-1, upper -C_{i+1}^-1 R_{i+1}^T
    diag = R @ c_inv[:-1] @ r_t + c_inv[1:]
    upper = -c_inv[1:-1] @ r_t[1:]
    cd = c_inv @ d
    rhs = -(b - R @ cd[:-1] + cd[1:])
    lam = _block_tridiagonal_solve(diag, upper, rhs)
    bt_lam = jnp.zeros_like(d).at[:-1].add(-r_t @ lam).at[1:].add(lam)
    return -c_inv @ (d + bt_lam)


def kkt_dense(C, d, R, b):
    """The same coefficients as :func:`shadowing_coefficients` from the full KKT matrix, assembled
    and solved densely with NumPy (a reference for tests; :math:`O(K^3 n_u^3)`)."""
    C, d, R, b = (np.asarray(x, dtype=float) for x in (C, d, R, b))
    K, n_u = C.shape[0], C.shape[1]
    p = d.shape[-1]
    n_a, n_l = K * n_u, (K - 1) * n_u
    kkt = np.zeros((n_a + n_l, n_a + n_l))
    for i in range(K):
        kkt[i * n_u:(i + 1) * n_u, i * n_u:(i + 1) * n_u] = C[i]
    for i in range(K - 1):
        row = n_a + i * n_u
        kkt[row:row + n_u, i * n_u:(i + 1) * n_u] = -R[i]
        kkt[row:row + n_u, (i + 1) * n_u:(i + 2) * n_u] = np.eye(n_u)
    kkt[:n_a, n_a:] = kkt[n_a:, :n_a].T
    rhs = np.concatenate([-d.reshape(n_a, p), b.reshape(n_l, p)])
    return np.linalg.solve(kkt, rhs)[:n_a].reshape(K, n_u, p)
