"""Numbers a user typed, as written back: without the rounding noise of the arithmetic between.

A value that came from the user (``revolutions = 3``, a swept range ``{start = 0.5, stop = 0.9,
num = 9}``, a start value) reaches an output file through float64 arithmetic (``t_end`` from the
revolutions and back, ``numpy.linspace``, a log/logit transform and its inverse), which leaves
an error in the 16th or 17th significant digit: ``3.0000000000000004``, ``0.7000000000000001``.
:func:`as_typed` rounds to :data:`DIGITS` significant digits, the most a float64 holds for every
decimal number (``DBL_DIG``): a number typed with at most 15 digits comes back exactly, and the
change is below 5e-16 relative. Computed results (estimates, metrics) are written as computed.
"""

from __future__ import annotations

import math
import numbers

#: Significant decimal digits that survive a float64 round trip for every decimal number.
DIGITS = 15


def as_typed(value):
    """``value`` rounded to :data:`DIGITS` significant digits (``0.7000000000000001`` ->
    ``0.7``); None, integers, booleans and non-finite floats unchanged; a NumPy array or a list
    element-wise (a float array stays one)."""
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return value if isinstance(value, (bool, int)) else int(value)
    if isinstance(value, (list, tuple)):
        return type(value)(as_typed(v) for v in value)
    if hasattr(value, "shape") and getattr(value, "ndim", 0) > 0:
        import numpy as np

        return np.array([as_typed(float(v)) for v in np.ravel(value)], dtype=float).reshape(np.shape(value))
    v = float(value)
    return float(f"{v:.{DIGITS}g}") if math.isfinite(v) else v
