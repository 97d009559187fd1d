"""The static part of a sweep (:class:`Plan`): everything the compiled chunk function depends
on besides the mechanism's numbers and the swept values. Hashable: a jit static argument, so a
later sweep with the same plan (other numbers) reuses the compilation."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..integrate import Settings


@dataclass(frozen=True)
class Plan:
    """Static description of the runs of one compiled chunk.

    Attributes:
        names: swept parameter names, in the column order of the (B, P) values.
        ideal_names: those that also apply to the ideal-joint mechanism.
        revolutions: crank revolutions per run; ``t_end = revolutions * 2 pi / |omega|`` [s].
        n_out: output samples per run (``revolutions * samples_per_revolution + 1``).
        start: first output sample of the metrics window (after the transient).
        section: output sample indices of the Poincare section.
        settings: how every run is integrated (the sweep's :attr:`SweepConfig.run_settings
            <jaxclear.sweep.SweepConfig.run_settings>`), as :func:`static_settings` makes it
            hashable; each run replaces its ``t_end`` and ``n_out``
            (:func:`jaxclear.sweep.batch.run_settings`).
        trajectories: also return the time series.
        mesh: the 1-D ``jax.sharding.Mesh`` (axis ``"batch"``) the chunk is sharded over
            (``None`` for an unbatched call of the per-run function).
        channels: named output channels summarized per run (and stored as time series with
            ``trajectories``).
        side_by_side: whether a device integrates its runs side by side (``jax.vmap``, True)
            or one after another (``jax.lax.map``, False); ``None`` (default): chosen for the
            device (:func:`jaxclear.sweep.batch.one_by_one`).
    """

    names: tuple[str, ...]
    ideal_names: tuple[str, ...]
    revolutions: float
    n_out: int
    start: int
    section: tuple[int, ...]
    settings: Settings
    trajectories: bool
    mesh: Any
    side_by_side: bool | None = None
    channels: tuple[str, ...] = ()


def make_plan(cfg, mesh, trajectories: bool | None = None, ideal: bool = True) -> Plan:
    """The :class:`Plan` of a validated :class:`~jaxclear.sweep.SweepConfig` on ``mesh``
    (``trajectories`` default: the config's; ``ideal=False``: no ideal-joint parameters)."""
    return Plan(
        names=cfg.names, ideal_names=cfg.ideal_names if ideal else (), revolutions=float(cfg.revolutions),
        n_out=cfg.n_out, start=cfg.window_start, section=cfg.section, settings=static_settings(cfg.run_settings),
        trajectories=bool(cfg.trajectories if trajectories is None else trajectories), mesh=mesh,
        channels=tuple(cfg.channel_units),
    )


def static_settings(s: Settings) -> Settings:
    """``s`` as a part of a :class:`Plan`: what a run replaces set aside (``t_end`` 1 s,
    ``t_start`` 0, ``throw`` False, ``progress`` False) and its array leaves (the Baumgarte
    gains) as Python numbers, so that it hashes (a static argument of the compiled chunk; equal
    settings, equal plans). :func:`dynamic_settings` turns it back."""
    s = dataclasses.replace(s, t_end=jnp.asarray(1.0), t_start=0.0, throw=False, progress=False)
    return jax.tree.map(lambda a: np.asarray(a).item(), s)


def dynamic_settings(s: Settings) -> Settings:
    """A :class:`Plan`'s settings with their leaves as arrays again (:func:`static_settings`)."""
    return jax.tree.map(jnp.asarray, s)
