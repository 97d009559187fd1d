"""What :func:`~jaxclear.shadowing.nilss` returns."""

from __future__ import annotations

import equinox as eqx
import jax
import numpy as np


class ShadowingResult(eqx.Module):
    """The derivative of a long-time average by non-intrusive least-squares shadowing.

    Attributes:
        derivative: :math:`d\\langle J\\rangle/ds`, the mean over the members, of ``s``'s shape.
        derivative_error: its standard error (the members' spread / sqrt(members)).
        average: :math:`\\langle J\\rangle`, the mean over the members.
        average_error: its standard error.
        member_derivatives: ``(members, *s.shape)``: each trajectory's derivative.
        member_averages: ``(members,)``: each trajectory's average.
        exponents: ``(members, n_unstable)``: the growth rates of the homogeneous tangents' flow-normal
            parts (the largest Lyapunov exponents besides the flow direction's zero; NILSAS: the
            homogeneous adjoints' growth backwards in time, the same exponents). Where the last
            is clearly positive, more directions are unstable than ``n_unstable`` holds, and the
            derivative is not a shadowing one.
        steps: ``(members,)``: the solver's accepted steps over the segments.
        time: the averaging time of each member, ``(segments - discard) * segment_time``.
        segments: the number of segments of each member.
        discard: the segments left out of the averages: at the start (NILSS), at the end (NILSAS).
        segment_time: the length of a segment.
        n_unstable: the number of homogeneous tangents.
        blocks: True where ``member_*`` are consecutive blocks of one run (batch means,
            :func:`jaxclear.steady_derivatives`) rather than independent trajectories.
        method: ``"NILSS"`` (tangents, :func:`~jaxclear.shadowing.nilss`) or ``"NILSAS"``
            (adjoints, :func:`~jaxclear.shadowing.nilsas`).
    """

    derivative: jax.Array
    derivative_error: jax.Array
    average: jax.Array
    average_error: jax.Array
    member_derivatives: jax.Array
    member_averages: jax.Array
    exponents: jax.Array
    steps: jax.Array
    time: float = eqx.field(static=True)
    segments: int = eqx.field(static=True)
    discard: int = eqx.field(static=True)
    segment_time: float = eqx.field(static=True)
    n_unstable: int = eqx.field(static=True)
    blocks: bool = eqx.field(static=True, default=False)
    method: str = eqx.field(static=True, default="NILSS")

    @property
    def members(self) -> int:
        """The number of independent trajectories."""
        return int(self.member_averages.shape[0])

    @property
    def _where(self) -> str:
        return " at the end" if self.method == "NILSAS" else ""

    def summary(self) -> str:
        """A few lines of text: the derivative and the average with their standard errors, the
        run's size and the exponents of the homogeneous tangents."""
        d = np.atleast_1d(np.asarray(self.derivative))
        e = np.atleast_1d(np.asarray(self.derivative_error))
        lines = [
            f"{self.method} derivative of a long-time average",
            f"  <J>       = {float(self.average):.6g} +- {float(self.average_error):.2g} (standard error)",
            *(f"  d<J>/ds[{i}] = {d[i]:.6g} +- {e[i]:.2g}" for i in range(d.size)),
            ("  one run of" if self.blocks else f"  {self.members} members x")
            + f" {self.segments} segments x {self.segment_time:g}"
            + (f" ({self.discard} left out{self._where})" if self.discard else "")
            + (f": {self.time:g} time units averaged in {self.members} blocks" if self.blocks
               else f": {self.time:g} time units each averaged") + f", {int(np.sum(self.steps))} steps",
        ]
        if self.n_unstable:
            lam = np.mean(np.asarray(self.exponents), axis=0)
            kind = "adjoints" if self.method == "NILSAS" else "tangents"
            lines.append(f"  exponents of the homogeneous {kind}: " + ", ".join(f"{x:.4g}" for x in lam))
        return "\n".join(lines)
