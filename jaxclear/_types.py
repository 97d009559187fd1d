"""Shared type aliases (jaxtyping), the one place they are defined."""

from __future__ import annotations

from jaxtyping import Array, ArrayLike, Bool, Float, Int

Scalar = Float[Array, ""]  #: a float64 scalar array
Vec2 = Float[Array, "2"]  #: a planar vector [x, y]
Vec3 = Float[Array, "3"]  #: body coordinates [x, y, phi]
BoolScalar = Bool[Array, ""]
IntScalar = Int[Array, ""]

__all__ = ["Array", "ArrayLike", "Float", "Scalar", "Vec2", "Vec3", "BoolScalar", "IntScalar"]
