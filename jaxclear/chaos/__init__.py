r"""How chaotic is a mechanism's motion: Lyapunov exponents from the tangent dynamics, spectra and
tests for chaos.

* :mod:`~jaxclear.chaos.manifold`: the phase space (the tangent space of the constraint
  manifold) and its metric;
* :mod:`~jaxclear.chaos.benettin`: Benettin's method with QR renormalisation on the
  error-controlled tangents (:class:`LyapunovResult`);
* :mod:`~jaxclear.chaos.lyapunov`: :func:`lyapunov`, :func:`lyapunov_map`, :func:`trajectory`;

Theory: docs/theory/chaos.md.
"""

from .benettin import STATUS, LyapunovResult
from .lyapunov import MIN_INTERVALS, LyapunovError, LyapunovMap, lyapunov, lyapunov_map, trajectory

__all__ = ["STATUS", "MIN_INTERVALS", "LyapunovError", "LyapunovMap", "LyapunovResult", "lyapunov", "lyapunov_map",
           "trajectory"]
