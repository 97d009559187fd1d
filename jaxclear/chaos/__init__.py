r"""How chaotic is a mechanism's motion: Lyapunov exponents from the tangent dynamics, spectra and
tests for chaos.

* :mod:`~jaxclear.chaos.manifold`: the phase space (the tangent space of the constraint
  manifold) and its metric;
* :mod:`~jaxclear.chaos.benettin`: Benettin's method with QR renormalisation on the
  error-controlled tangents (:class:`LyapunovResult`);
* :mod:`~jaxclear.chaos.lyapunov`: :func:`lyapunov`, :func:`lyapunov_map`, :func:`trajectory`;
* :mod:`~jaxclear.chaos.signals`: power spectral density (Welch), the 0-1 test for chaos,
  Rosenstein's time-series exponent; Poincare sections and their period are in
  :mod:`jaxclear.analysis.sections`;
* :mod:`~jaxclear.chaos.shadowing`: :func:`steady_derivatives`, derivatives of long-time
  averages of the steady running by least-squares shadowing (NILSS) on the same tangents;
* :mod:`~jaxclear.chaos.report`, :mod:`~jaxclear.chaos.figures`: one operating point's tables
  and figures (``jaxclear chaos``).

Theory: docs/theory/chaos.md.
"""

from .benettin import LyapunovResult
from .lyapunov import MIN_INTERVALS, LyapunovError, LyapunovMap, check_convergence, lyapunov, lyapunov_map, trajectory
from .signals import channel_series, psd, rosenstein, zero_one_test
from .report import ChannelReport, ChaosReport, characterise, write_report
from .shadowing import ShadowingWarning, steady_derivatives

__all__ = ["MIN_INTERVALS", "ChannelReport", "ChaosReport", "LyapunovError", "LyapunovMap", "LyapunovResult",
           "ShadowingWarning", "channel_series", "characterise", "check_convergence", "lyapunov", "lyapunov_map", "psd",
           "rosenstein", "steady_derivatives", "trajectory", "write_report", "zero_one_test"]


def __getattr__(name: str):
    """``STATUS`` (the old chaos-only codes 0 ok, 1 run failed, 2 overflow), deprecated:
    :attr:`LyapunovResult.status` holds a :class:`jaxclear.RESULTS` code, whose message is
    :data:`jaxclear.STATUS`; served here as that map for one release."""
    if name == "STATUS":
        import warnings

        from .._errors import STATUS as RUN_STATUS
        from .benettin import STATUS_DEPRECATED

        warnings.warn(STATUS_DEPRECATED.format("jaxclear.chaos.STATUS"), DeprecationWarning, stacklevel=2)
        return RUN_STATUS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
