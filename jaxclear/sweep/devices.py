"""Devices: the 1-D mesh the batch is sharded over, chunk sizing, and moving a chunk onto the
mesh and back (one process or several joined by ``jax.distributed``)."""

from __future__ import annotations

import os

import jax
import numpy as np
from jax.experimental import multihost_utils
from jax.sharding import Mesh, NamedSharding, PartitionSpec

#: Bytes per output sample and per run assumed by :func:`auto_chunk_size` (state, derivatives,
#: reactions, contact outputs of the solution plus the ideal run and the metrics' temporaries).
BYTES_PER_SAMPLE = 4096
DEFAULT_RUNS_PER_DEVICE = 16


def make_mesh(devices: int | None = None) -> Mesh:
    """A 1-D :class:`jax.sharding.Mesh` named ``"batch"`` over the first ``devices`` of
    ``jax.devices()`` (every device of every process by default)."""
    devs = jax.devices()
    if devices is not None:
        devs = devs[:devices]
    return Mesh(np.array(devs), ("batch",))


def auto_chunk_size(n_out: int, n_devices: int, n_runs: int, memory_bytes: int | None = None,
                    trajectories: bool = False) -> int:
    """Runs per chunk: :data:`DEFAULT_RUNS_PER_DEVICE` per device, fewer if the outputs of a
    chunk (:data:`BYTES_PER_SAMPLE` per sample and run, doubled with trajectories) would exceed
    a quarter of ``memory_bytes`` (default: the device's or the host's memory), and no more than
    the runs rounded up to a multiple of the devices."""
    if memory_bytes is None:
        memory_bytes = _memory_bytes()
    per_run = BYTES_PER_SAMPLE * n_out * (2 if trajectories else 1)
    fit = max(1, int(memory_bytes // 4 // per_run))
    size = min(DEFAULT_RUNS_PER_DEVICE * n_devices, fit)
    size = min(size, n_runs + (-n_runs) % n_devices)
    return max(n_devices, size - size % n_devices)


def chunk_size(cfg, n_devices: int) -> int:
    """The chunk size of a sweep on ``n_devices``: :func:`auto_chunk_size` for ``"auto"``, else
    the configured size rounded up to a multiple of the devices."""
    if cfg.chunk_size == "auto":
        return auto_chunk_size(cfg.n_out, n_devices, cfg.n_runs, trajectories=cfg.trajectories)
    return int(cfg.chunk_size) + (-int(cfg.chunk_size)) % n_devices


def _memory_bytes() -> int:
    try:
        stats = jax.local_devices()[0].memory_stats() or {}
        if "bytes_limit" in stats:
            return int(stats["bytes_limit"])
    except Exception:  # noqa: BLE001 - CPU devices have no memory stats
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 4 << 30


def put_chunk(values: np.ndarray, mesh: Mesh):
    """Place a (B, P) host array on the mesh, batch axis split (works across processes)."""
    sharding = NamedSharding(mesh, PartitionSpec("batch"))
    if jax.process_count() == 1:
        return jax.device_put(values, sharding)
    return jax.make_array_from_callback(values.shape, sharding, lambda index: values[index])


def fetch_chunk(tree) -> dict:
    """The chunk's outputs as host NumPy arrays (gathered from every process)."""
    if jax.process_count() == 1:
        return jax.tree_util.tree_map(np.asarray, tree)
    return jax.tree_util.tree_map(np.asarray, multihost_utils.process_allgather(tree, tiled=True))


def agree_on_done(done: set[int], n_runs: int) -> set[int]:
    """Process 0's set of finished run indices, broadcast to every process (one process: as is)."""
    if jax.process_count() == 1:
        return done
    mask = np.zeros(n_runs, dtype=np.int32)
    mask[list(done)] = 1
    mask = np.asarray(multihost_utils.broadcast_one_to_all(mask))
    return set(np.nonzero(mask)[0].tolist())


def barrier(name: str):
    """Wait for every process (no-op with one)."""
    if jax.process_count() > 1:
        multihost_utils.sync_global_devices(name)
