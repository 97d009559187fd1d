"""The driver: :func:`run_sweep` runs (or resumes) a sweep chunk by chunk.

Chunks are laid out over the global run indices (chunk ``c`` = runs ``c*S .. c*S+S-1``, the
last one padded by repeating its last run, the padded rows dropped), so every chunk has the
same shape (one compilation per sweep) and a resumed sweep batches every run exactly as an
uninterrupted one does and gets the same bits. With several processes (``jax.distributed``)
every process feeds its own shards and process 0 alone writes the files.
"""

from __future__ import annotations

import os

import jax
import numpy as np
from tqdm import tqdm

from .._checkpoint import locked

from .batch import run_chunk
from .config import SweepConfig
from .devices import agree_on_done, barrier, chunk_size, fetch_chunk, make_mesh, put_chunk
from .plan import Plan, make_plan
from .results import SweepResult, read_results
from .store import prepare_output, write_chunk


def _layout(cfg: SweepConfig):
    """(mesh, chunk size, layout dict for the manifest)."""
    mesh = make_mesh(cfg.devices)
    n_dev = mesh.devices.size
    chunk = chunk_size(cfg, n_dev)
    layout = {"chunk_size": chunk, "devices": n_dev, "processes": jax.process_count(),
              "platform": jax.devices()[0].platform}
    return mesh, chunk, layout


def _todo(cfg: SweepConfig, chunk: int, done: set[int]) -> list[int]:
    """Indices of the chunks with at least one run not yet done."""
    n_chunks = -(-cfg.n_runs // chunk)
    return [c for c in range(n_chunks)
            if any(i not in done for i in range(c * chunk, min((c + 1) * chunk, cfg.n_runs)))]


def _compute(cfg: SweepConfig, plan: Plan, c: int, chunk: int) -> tuple[int, dict]:
    """Chunk ``c`` computed (padded to ``chunk`` runs, padding dropped): (first run, outputs)."""
    lo, hi = c * chunk, min((c + 1) * chunk, cfg.n_runs)
    rows = cfg.values[lo:hi]
    padded = np.concatenate([rows, np.repeat(rows[-1:], chunk - (hi - lo), axis=0)], axis=0)
    res = fetch_chunk(run_chunk(put_chunk(padded, plan.mesh), cfg.base_mechanism, cfg.ideal, plan))
    return lo, {k: v[: hi - lo] for k, v in res.items()}


def run_sweep(cfg: SweepConfig, out: str | None = None, restart: bool = False,
              progress: bool | None = None) -> SweepResult:
    """Run (or resume) a sweep; returns its results read back from disk. When it finishes,
    ``OUT/results.nc`` holds them as a labelled dataset (:meth:`SweepResult.to_xarray`).

    Args:
        cfg: a validated :class:`SweepConfig` (errors were raised when it was built).
        out: output folder (default ``cfg.out``).
        restart: discard results of a previous sweep in ``out`` instead of resuming.
        progress: tqdm bar over the chunks (default ``cfg.progress``).
    """
    out = os.fspath(out if out is not None else cfg.out)
    progress = cfg.progress if progress is None else progress
    lead = jax.process_index() == 0
    # one writer per folder: a second sweep into it fails at once (no row written twice)
    with locked(out if lead else None, "sweep"):
        return _run_sweep(cfg, out, restart, progress, lead)


def _run_sweep(cfg: SweepConfig, out: str, restart: bool, progress: bool, lead: bool) -> SweepResult:
    """:func:`run_sweep` inside the folder's lock."""
    mesh, chunk, layout = _layout(cfg)
    done = prepare_output(cfg, out, restart, layout) if lead else set()
    done = agree_on_done(done, cfg.n_runs)  # every process must agree on the work left
    plan = make_plan(cfg, mesh)
    todo = _todo(cfg, chunk, done)
    n_chunks = -(-cfg.n_runs // chunk)
    show = progress and lead
    if done and show:
        tqdm.write(f"jaxclear sweep: resuming in {out}: {len(done)} of {cfg.n_runs} runs already done")
    computed = 0
    if todo and show:
        tqdm.write("jaxclear sweep: compiling; the progress bar starts after the first chunk")
    bar = None
    try:
        for c in todo:
            lo, res = _compute(cfg, plan, c, chunk)
            if lead:
                computed += write_chunk(cfg, out, c, lo, res, done)
            if bar is None:  # started after the first chunk (compilation), so the ETA leaves it out
                bar = tqdm(total=n_chunks, initial=n_chunks - len(todo) + 1, unit="chunk",
                           desc="sweep (resumed)" if done else "sweep", disable=not show, dynamic_ncols=True)
            else:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    barrier("jaxclear-sweep-done")
    if not lead:
        return SweepResult(out, {}, cfg.names, np.zeros(0), cfg.axes, "grid" if cfg.grid is not None else "list",
                           computed)
    res = read_results(out)
    res.computed = computed
    res.write(out, plots=False)  # results.nc (the CSV, manifest and chunks were written as it ran)
    return res
