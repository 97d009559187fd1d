"""The driver: :func:`run_sweep` runs (or resumes) a sweep chunk by chunk.

Chunks are laid out over the global run indices (chunk ``c`` = runs ``c*S .. c*S+S-1``, the
last one padded by repeating its last run, the padded rows dropped), so every chunk has the
same shape (one compilation per sweep) and a resumed sweep batches every run exactly as an
uninterrupted one does and gets the same bits. With several processes (``jax.distributed``)
every process feeds its own shards and process 0 alone writes the files. The chunks, their
padding and their loop are the lane runner's (:mod:`jaxclear.sweep.lanes`).
"""

from __future__ import annotations

import os

import jax
import numpy as np
from tqdm import tqdm

from .._checkpoint import locked

from .batch import run_chunk
from .config import SweepConfig
from .devices import agree_on_done, barrier, chunk_size, make_mesh
from .lanes import chunks_todo, compute_chunk, run_chunks
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
    return chunks_todo(cfg.n_runs, chunk, done)


def _compute(cfg: SweepConfig, plan: Plan, c: int, chunk: int) -> tuple[int, dict]:
    """Chunk ``c`` computed (padded to ``chunk`` runs, padding dropped): (first run, outputs)."""
    res = compute_chunk(run_chunk, cfg.values, c, chunk, plan.mesh, cfg.base_mechanism, cfg.ideal, plan)
    return c * chunk, res


def run_sweep(cfg: SweepConfig, out: str | None = None, restart: bool = False,
              progress: bool | None = None, write_dataset: bool = True) -> SweepResult:
    """Run (or resume) a sweep; returns its results read back from disk. When it finishes,
    ``OUT/results.nc`` holds them as a labelled dataset (:meth:`SweepResult.to_xarray`).

    Args:
        cfg: a validated :class:`SweepConfig` (errors were raised when it was built).
        out: output folder (default ``cfg.out``).
        restart: discard results of a previous sweep in ``out`` instead of resuming.
        progress: tqdm bar over the chunks (default ``cfg.progress``).
        write_dataset: write ``OUT/results.nc`` when it finishes (default). ``False`` leaves it to
            the caller's :meth:`SweepResult.write` (``jaxclear sweep``: the dataset and the
            figures, once); what the runs write as they go (``runs.csv``, ``manifest.json``,
            ``chunks/``, from which a killed sweep resumes) is the same either way.
    """
    out = os.fspath(out if out is not None else cfg.out)
    progress = cfg.progress if progress is None else progress
    lead = jax.process_index() == 0
    # one writer per folder: a second sweep into it fails at once (no row written twice)
    with locked(out if lead else None, "sweep"):
        return _run_sweep(cfg, out, restart, progress, lead, write_dataset)


def _run_sweep(cfg: SweepConfig, out: str, restart: bool, progress: bool, lead: bool,
               write_dataset: bool) -> SweepResult:
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

    def write(c, computed_chunk):
        nonlocal computed
        lo, res = computed_chunk
        if lead:
            computed += write_chunk(cfg, out, c, lo, res, done)

    # the lane runner's chunk loop; _compute looked up at each call (tests count its calls)
    run_chunks(todo, n_chunks, lambda c: _compute(cfg, plan, c, chunk), write, show=show,
               desc="sweep", resumed=bool(done))
    barrier("jaxclear-sweep-done")
    if not lead:
        return SweepResult(out, {}, cfg.names, np.zeros(0), cfg.axes, "grid" if cfg.grid is not None else "list",
                           computed)
    res = read_results(out)
    res.computed = computed
    if write_dataset:
        res.write(out, plots=False)  # results.nc (the CSV, manifest and chunks were written as it ran)
    return res
