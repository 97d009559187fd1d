r"""Derivatives of long-time averages of chaotic motions by shadowing.

* :func:`nilss`: non-intrusive least-squares shadowing (Ni and Wang 2017) for a general ODE
  :math:`\dot u = f(u, s)`, batched over independent trajectories whose spread is the error
  estimate; returns a :class:`ShadowingResult`.
* :func:`nilsas`: its adjoint form (Ni and Talnikar 2019), :math:`n_u + 1` adjoint solutions for
  any number of parameters, where :func:`nilss` integrates one tangent per parameter;
* :func:`shadowing_coefficients`: its small least-squares problem (the KKT system over the
  segments, solved block by block; :func:`coefficients` from the segments' records);
  :func:`derivative_terms`: the derivative's terms from the
  segments' records (:class:`SegmentRecord`, :class:`Integrals`; :func:`positive_qr` the
  renormalisation), which the mechanisms'
  shadowing (:func:`jaxclear.chaos.steady_derivatives`) fills from the engine's tangents.

Theory: docs/theory/shadowing.md.
"""

from ._least_squares import kkt_dense, shadowing_coefficients
from ._nilsas import nilsas
from ._nilss import coefficients, derivative_terms, nilss
from ._result import ShadowingResult
from ._segments import Integrals, SegmentRecord, positive_qr

__all__ = ["Integrals", "SegmentRecord", "ShadowingResult", "coefficients", "derivative_terms", "kkt_dense",
           "nilsas", "nilss", "positive_qr", "shadowing_coefficients"]
