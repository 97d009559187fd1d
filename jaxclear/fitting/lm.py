r"""The pieces of the fit's Levenberg-Marquardt that optimistix does not ship: Nielsen's damping
update (an optimistix search) and a damped Gauss-Newton descent that extends an accepted step
along its direction and caps every step (an optimistix descent). They plug into
:class:`optimistix.LevenbergMarquardt` (its ``search`` and ``descent``), which still runs the
loop (``init`` / ``step`` / ``terminate``).

Protocol between the two: the search hands the descent a positive ``step_size`` (``1 /
lambda``: a damped Gauss-Newton step from the last accepted point) or a negative one ``-m``
(an extension trial: ``m`` times the last accepted move, ``m = 1`` right after a
Gauss-Newton step, ``m = 2`` after an accepted extension, so the total step from the point
before the Gauss-Newton step doubles each time: ``2 d, 4 d, 8 d``).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import optimistix as optx


class NielsenState(eqx.Module):
    """``step_size`` (``1 / lambda``), ``nu`` (factor of ``lambda`` at the next rejection) and
    ``ext`` (0: the trial being evaluated is a Gauss-Newton step; ``k > 0``: its ``k``-th
    extension)."""

    step_size: jax.Array
    nu: jax.Array
    ext: jax.Array


class NielsenTrustRegion(optx.AbstractSearch):
    r"""Nielsen's damping update for Levenberg-Marquardt, as an optimistix search.

    A Gauss-Newton trial is accepted when it lowers ``0.5 |r|^2`` at all (gain ratio ``rho`` =
    actual over predicted decrease > 0); ``lambda`` then shrinks by ``max(1/3, 1 - (2 rho -
    1)^3)`` and ``nu`` is reset to 2; a rejected trial multiplies ``lambda`` by ``nu`` and
    doubles ``nu`` (Nielsen 1999, "Damping parameter in Marquardt's method", IMM-REP-1999-05,
    DTU; Madsen, Nielsen & Tingleff 2004, "Methods for non-linear least squares problems",
    algorithm 3.16). Unlike :class:`optimistix.ClassicalTrustRegion` (``lambda`` unchanged unless
    ``rho > 0.99``), the damping keeps falling while the Gauss-Newton model is fair.

    After an accepted Gauss-Newton step, up to ``extend`` extension trials (see the module
    docstring) are evaluated and accepted while they lower the loss: in the curved valleys of
    impact-timing misfits the Gauss-Newton step is much shorter than the way to the minimum.
    The first extension that does not lower the loss is rejected and the next trial is a
    Gauss-Newton step from the last accepted point (``lambda`` unchanged)."""

    extend: int = eqx.field(static=True, default=3)

    def init(self, y, f_info_struct) -> NielsenState:
        del y, f_info_struct
        # strongly typed, as :meth:`step` returns them: a weakly typed scalar (``jnp.array(1.0)``)
        # made the solver's step a new program after its first call (traced and compiled twice)
        return NielsenState(step_size=jnp.asarray(1.0, dtype=float), nu=jnp.asarray(2.0, dtype=float),
                            ext=jnp.asarray(0, dtype=int))

    def predict_reduction(self, y_diff, f_info):
        """Predicted change of ``0.5 |r|^2`` (negative for a decrease) along ``y_diff`` (the
        Gauss-Newton model, as :class:`optimistix.ClassicalTrustRegion`)."""
        return optx.ClassicalTrustRegion().predict_reduction(y_diff, f_info)

    def step(self, first_step, y, y_eval, f_info, f_eval_info, state: NielsenState):
        y_diff = jax.tree_util.tree_map(lambda a, b: a - b, y_eval, y)
        predicted = self.predict_reduction(y_diff, f_info)
        actual = f_eval_info.as_min() - f_info.as_min()
        is_ext = state.ext > 0
        lower = (actual < 0) & jnp.isfinite(actual)
        ok = lower & (is_ext | (predicted < 0))
        rho = jnp.where(ok & (predicted < 0), actual / jnp.where(predicted < 0, predicted, -1.0), 0.0)
        shrink = jnp.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
        accept = ok | first_step
        gn_ok = ok & jnp.invert(first_step) & jnp.invert(is_ext)
        step_size = jnp.where(gn_ok, state.step_size / shrink,
                              jnp.where(first_step | is_ext | ok, state.step_size, state.step_size / state.nu))
        nu = jnp.where(accept | is_ext, 2.0, 2.0 * state.nu)
        ext = jnp.where(gn_ok & (self.extend > 0), 1,
                        jnp.where(is_ext & ok & (state.ext < self.extend), state.ext + 1, 0))
        handed = jnp.where(ext > 0, -jnp.where(ext == 1, 1.0, 2.0), step_size)
        return handed, accept, optx.RESULTS.successful, NielsenState(step_size, nu, ext)


class ExtendedDescentState(eqx.Module):
    """The damped descent's state at the last accepted point ``y_cur`` and the accepted point
    before it ``y_prev``."""

    inner: eqx.Module
    y_prev: jax.Array
    y_cur: jax.Array


class ExtendedDampedNewtonDescent(optx.AbstractDescent):
    r""":class:`optimistix.DampedNewtonDescent` (``(J^T J + lambda I) dy = -J^T r``, QR) for a
    positive ``step_size = 1 / lambda``; for a negative one ``-m`` the extension ``m (y_cur -
    y_prev)``. Every step is then scaled down so that no coordinate of ``dy / scale`` (the
    fit's unknowns ``x = y / scale``, transformed parameters and window states) exceeds
    ``max_step`` (1.5 is a factor 4.5 in a log parameter): a parameter the data do not yet
    constrain cannot run off."""

    scale: jax.Array
    max_step: float = 1.5
    linear_solver: lx.AbstractLinearSolver = lx.QR()

    def _damped(self):
        return optx.DampedNewtonDescent(linear_solver=self.linear_solver)

    def init(self, y, f_info_struct) -> ExtendedDescentState:
        return ExtendedDescentState(self._damped().init(y, f_info_struct), y, y)

    def query(self, y, f_info, state: ExtendedDescentState) -> ExtendedDescentState:
        return ExtendedDescentState(self._damped().query(y, f_info, state.inner), state.y_cur, y)

    def step(self, step_size, state: ExtendedDescentState):
        gn, result = self._damped().step(jnp.where(step_size > 0, step_size, 1.0), state.inner)
        diff = jnp.where(step_size > 0, gn, -step_size * (state.y_cur - state.y_prev))
        largest = jnp.max(jnp.abs(diff / self.scale), initial=0.0)
        diff = diff * jnp.minimum(1.0, self.max_step / jnp.where(largest > 0, largest, 1.0))
        result = optx.RESULTS.where(step_size > 0, result, optx.RESULTS.successful)
        return diff, result


def with_scale(solver, scale):
    """``solver`` with its :class:`ExtendedDampedNewtonDescent`'s ``scale`` set (unchanged if
    it has none)."""
    descent = getattr(solver, "descent", None)
    if not isinstance(descent, ExtendedDampedNewtonDescent):
        return solver
    return eqx.tree_at(lambda s: s.descent.scale, solver, jnp.asarray(scale, dtype=float))


def levenberg_marquardt(rtol: float, atol: float, extend: int = 3, max_step: float = 1.5):
    """:class:`optimistix.LevenbergMarquardt` with Nielsen's damping update, step extension
    and step cap (:class:`NielsenTrustRegion`, :class:`ExtendedDampedNewtonDescent`)."""
    lm = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    lm = eqx.tree_at(lambda s: s.search, lm, NielsenTrustRegion(extend=extend))
    return eqx.tree_at(lambda s: s.descent, lm, ExtendedDampedNewtonDescent(jnp.ones(()), max_step))
