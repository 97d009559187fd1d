r"""Planar vector geometry, written elementwise: the one place these formulas live.

Elementwise 2-vector arithmetic lets XLA on CPU fuse each formula with its neighbours, while a
2x2 ``dot`` would be a kernel call of its own (the right-hand side of a planar mechanism is a
few dozen flops per kernel, so kernel count sets its cost).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._types import Scalar, Vec2


@jax.jit  # traced once per shape and reused (called hundreds of times in one program's trace)
def rotate(phi: Scalar, v: Vec2) -> Vec2:
    r""":math:`A(\phi) v` with :math:`A(\phi) = [[\cos\phi, -\sin\phi], [\sin\phi, \cos\phi]]`."""
    c, s = jnp.cos(phi), jnp.sin(phi)
    return jnp.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def perp(v: Vec2) -> Vec2:
    """Rotate a 2-vector by +90 degrees: ``[-v_y, v_x]``."""
    return jnp.stack([-v[1], v[0]])


def cross2(a: Vec2, b: Vec2) -> Scalar:
    """Planar cross product :math:`a_x b_y - a_y b_x`."""
    return a[0] * b[1] - a[1] * b[0]


def dot2(a: Vec2, b: Vec2) -> Scalar:
    """:math:`a_x b_x + a_y b_y`."""
    return a[0] * b[0] + a[1] * b[1]


def safe_normal(v: Vec2) -> tuple[Scalar, Vec2]:
    """``(|v|, v/|v|)`` with finite values and gradients at ``v = 0`` (unit vector ``[1, 0]``
    there)."""
    e2 = v[0] ** 2 + v[1] ** 2
    nonzero = e2 > 1e-300
    safe = jnp.where(nonzero, v, jnp.array([1.0, 0.0], v.dtype))
    norm = jnp.sqrt(safe[0] ** 2 + safe[1] ** 2)
    return jnp.where(nonzero, norm, 0.0), safe / norm
