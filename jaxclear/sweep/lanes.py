r"""The one lane runner: lanes of one pure function over a batch of inputs, for every batch of
jaxclear (a sweep's runs, a design's operating points and ensemble members, a sampler's chains,
a tolerance study's batches (each a list sweep), the rows of :func:`jaxclear.lyapunov_map`).

**The rule** (:func:`lanes_one_by_one`, one for every batch): the lanes go *one after another*
(``jax.lax.map``) on a CPU device with single-kernel loops (:mod:`jaxclear._xla_flags`), *side by
side* (``jax.vmap``) elsewhere. On such a CPU the lanes of a ``vmap`` run one after another
inside the loop's kernel anyway, and the batch runs until its slowest lane is done, so one after
another each lane takes its own number of solver steps and nothing waits (measured on a sweep,
:func:`jaxclear.sweep.batch.one_by_one`: 217 against 130 runs/s on one CPU device); on an
accelerator ``vmap`` is what fills the device. A caller may overrule it where it documents why
(a sweep's ``side_by_side``, :func:`jaxclear.lyapunov_map`'s ``batch_size``: side by side in
batches of that many lanes, the batches one after another).

Three levels, each used by the one above:

* :func:`over_lanes` (inside a traced program): ``f`` over the leading axis of its arguments by
  the rule;
* :func:`on_devices` (inside a traced program): a lanes function with its rows split over a 1-D
  mesh of devices (``jax.shard_map``, axis ``"batch"``; :func:`jaxclear.sweep.devices.make_mesh`)
  and its other arguments replicated;
* the host's threads (:func:`host_map`, :func:`host_rows`): independent calls of compiled
  programs from host code (the fit's way in scoring its candidate starts, its windows evaluated
  one by one) spread over :func:`host_threads` Python threads. A CPU device runs one program's
  loop kernel on one core, and JAX releases the GIL while a program runs, so on two cores two
  threads score 1560 candidate starts of a fit window in 1.60 s where one call takes 2.95 s (the
  same numbers bit for bit: the lanes are independent);
* the host's chunks: :func:`padded_chunk` (chunk ``c`` is rows ``c*S .. c*S+S-1``, the last one
  padded by repeating its last row, so that every chunk has one shape and one compilation, and a
  resumed run batches every row as an uninterrupted one does), :func:`chunks_todo`,
  :func:`run_chunks` (the loop and its progress bar) and :func:`run_lanes` (all of it, with resume
  through the checkpoint protocol, :class:`jaxclear._checkpoint.Work`: every finished chunk an
  NPZ state ``chunks/chunk_NNNNNN.npz`` carrying the work's header, written atomically before the
  next chunk starts; a killed run resumes from the chunks on disk and computes only the others).
  The sweep writes its own files (``runs.csv``, its chunks) through the same loop.
"""

from __future__ import annotations

import os
import re
import threading
from concurrent.futures import Future, ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import PartitionSpec
from tqdm import tqdm

from .._xla_flags import loop_kernels_active
from .devices import fetch_chunk, put_chunk

#: The folder (in the output folder) of :func:`run_lanes`' chunk states.
CHUNK_DIR = "chunks"
_CHUNK_FILE = re.compile(r"^chunk_(\d{6})\.npz$")


def lanes_one_by_one(platform: str | None = None) -> bool:
    """The rule: whether independent lanes of work go one after another (``jax.lax.map``) rather
    than side by side (``jax.vmap``) on a device of ``platform`` (default: JAX's default
    backend): on CPU with single-kernel loops (the module's docstring says why)."""
    return (platform or jax.default_backend()) == "cpu" and loop_kernels_active()


def over_lanes(f, *args, one_by_one: bool | None = None, batch_size: int | None = None):
    """``f`` mapped over the leading axis of ``args`` (traceable): one lane after another
    (``jax.lax.map``) where ``one_by_one``, else side by side (``jax.vmap``), in batches of
    ``batch_size`` lanes one batch after another where that is given (``jax.lax.map(...,
    batch_size=)``). ``one_by_one`` None: the rule (:func:`lanes_one_by_one`) without a
    ``batch_size``, side by side in its batches with one. One after another, each lane takes its
    own number of solver steps; side by side on a CPU, every lane waits for the batch's slowest.
    A single lane is ``f`` called on it, its outputs given the leading axis: a ``jax.lax.map`` of
    one lane traced the lane again wherever it is differentiated (JAX linearizes a loop's body to
    find which carries have tangents; a one-member design's Jacobian traced 25 % longer)."""
    leaves = jax.tree_util.tree_leaves(args)
    if leaves and all(jnp.shape(x)[:1] == (1,) for x in leaves):
        lane = f(*jax.tree_util.tree_map(lambda x: x[0], args))
        return jax.tree_util.tree_map(lambda y: jnp.asarray(y)[None], lane)
    if one_by_one is None:
        one_by_one = batch_size is None and lanes_one_by_one()
    if one_by_one:
        if len(args) == 1:
            return jax.lax.map(f, args[0])
        return jax.lax.map(lambda a: f(*a), args)
    if batch_size is not None:
        if len(args) == 1:
            return jax.lax.map(f, args[0], batch_size=batch_size)
        return jax.lax.map(lambda a: f(*a), args, batch_size=batch_size)
    return jax.vmap(f)(*args)


#: Most host threads of :func:`host_threads` (whatever the CPUs), and the environment variable
#: that sets their number (1: everything on the calling thread).
MAX_HOST_THREADS = 8
HOST_THREADS_ENV = "JAXCLEAR_HOST_THREADS"


def host_threads() -> int:
    """Threads for independent host-side calls of compiled programs: ``JAXCLEAR_HOST_THREADS``
    where set (an integer >= 1), else the CPUs this process may run on, at most
    :data:`MAX_HOST_THREADS`."""
    given = os.environ.get(HOST_THREADS_ENV)
    if given:
        try:
            n = int(given)
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"{HOST_THREADS_ENV} = {given!r} must be an integer >= 1 (threads for independent "
                             "compiled calls; 1: none beside the calling one)")
        return n
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cpus, MAX_HOST_THREADS))


def host_map(f, items) -> list:
    """``[f(x) for x in items]``, the calls spread over :func:`host_threads` threads (in order;
    the first exception raised is raised here)."""
    items = list(items)
    n = min(host_threads(), len(items))
    if n <= 1:
        return [f(x) for x in items]
    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(f, items))


def ahead(f, *args) -> Future | None:
    """``f(*args)`` started on a thread of its own (a daemon: an interrupted caller does not wait for
    it), so that the programs a later call of the caller will run are traced and compiled while the
    caller goes on: XLA's compilation of one program keeps about one core busy (measured: 117 % of
    a CPU over a design's first evaluations on 2 cores), and tracing holds Python's lock, so on a
    host of several CPUs two programs' compilations overlap. Returns the future of ``f``'s result
    (an exception it raised is kept in it: this is a warm-up, the later call raises what it must),
    or None where :func:`host_threads` is 1 (nothing runs ahead)."""
    if host_threads() <= 1:
        return None
    done: Future = Future()

    def run():
        try:
            done.set_result(f(*args))
        except BaseException as e:  # noqa: BLE001 (kept for the caller, who decides)
            done.set_exception(e)

    threading.Thread(target=run, name="jaxclear-ahead", daemon=True).start()
    return done


def host_rows(f, rows: np.ndarray, min_rows: int = 8) -> np.ndarray:
    """``f(rows)`` for a lanes function ``f`` of host rows ``(n, ...) -> (n, ...)``, the rows split
    into :func:`host_threads` parts of one size (the last padded by repeating its last row: one
    compiled shape), each part on its own thread, the outputs concatenated in order and the
    padding dropped. Fewer than ``min_rows`` rows a part: one call."""
    rows = np.asarray(rows)
    n = len(rows)
    parts = min(host_threads(), n // max(min_rows, 1))
    if parts <= 1:
        return np.asarray(f(rows))
    size = -(-n // parts)
    chunks = [padded_chunk(rows, c, size)[2] for c in range(chunk_count(n, size))]
    out = host_map(lambda r: np.asarray(f(r)), chunks)
    return np.concatenate(out, axis=0)[:n]


def on_devices(lanes, mesh, rows, *shared):
    """``lanes(rows, *shared)`` with ``rows`` (leading axis a multiple of the mesh's devices)
    split over the 1-D ``mesh`` (axis ``"batch"``) and ``shared`` (pytrees: a mechanism, settings)
    on every device, their arrays passed in and the rest closed over. Traceable (call it inside
    ``jit``); the outputs' leading axis is the rows'."""
    arrays, static = eqx.partition(shared, eqx.is_array)

    def local(r, *arr):
        return lanes(r, *eqx.combine(arr, static))

    batch, whole = PartitionSpec("batch"), PartitionSpec()
    f = jax.shard_map(local, mesh=mesh, in_specs=(batch,) + (whole,) * len(shared), out_specs=batch,
                      check_vma=False)
    return f(rows, *arrays)


# ---- the host's chunks ------------------------------------------------------------------------


def chunk_count(n: int, chunk: int) -> int:
    """Chunks of ``chunk`` rows over ``n`` rows."""
    return -(-n // chunk)


def round_chunk(chunk: int, n_devices: int) -> int:
    """``chunk`` rounded up to a multiple of the devices (each device gets as many rows)."""
    return int(chunk) + (-int(chunk)) % n_devices


def padded_chunk(values: np.ndarray, c: int, chunk: int) -> tuple[int, int, np.ndarray]:
    """``(lo, hi, rows)``: chunk ``c`` is rows ``lo .. hi - 1`` of ``values``, padded to ``chunk``
    rows by repeating its last one (the padding's outputs are dropped)."""
    lo, hi = c * chunk, min((c + 1) * chunk, len(values))
    rows = values[lo:hi]
    return lo, hi, np.concatenate([rows, np.repeat(rows[-1:], chunk - (hi - lo), axis=0)], axis=0)


def chunks_todo(n: int, chunk: int, done) -> list[int]:
    """The chunks with at least one of the ``n`` rows not in ``done`` (row indices)."""
    return [c for c in range(chunk_count(n, chunk))
            if any(i not in done for i in range(c * chunk, min((c + 1) * chunk, n)))]


def run_chunks(todo, n_chunks: int, compute, write=None, *, show: bool = False, desc: str = "lanes",
               resumed: bool = False) -> None:
    """The chunk loop: ``write(c, compute(c))`` for every chunk ``c`` of ``todo`` in order, with a
    tqdm bar (``show``) over the ``n_chunks`` started after the first chunk (its compilation left
    out of the estimate of the time to go)."""
    bar = None
    try:
        for c in todo:
            res = compute(c)
            if write is not None:
                write(c, res)
            if bar is None:
                bar = tqdm(total=n_chunks, initial=n_chunks - len(todo) + 1, unit="chunk",
                           desc=f"{desc} (resumed)" if resumed else desc, disable=not show, dynamic_ncols=True)
            else:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()


def compute_chunk(compiled, values: np.ndarray, c: int, chunk: int, mesh, *shared) -> dict:
    """Chunk ``c`` of ``values`` through ``compiled(rows, *shared)`` (rows placed on ``mesh``),
    the padding dropped: a dict of host arrays with the chunk's rows."""
    lo, hi, rows = padded_chunk(values, c, chunk)
    res = fetch_chunk(compiled(put_chunk(rows, mesh), *shared))
    return {k: v[: hi - lo] for k, v in res.items()}


def chunk_file(c: int) -> str:
    """The state of chunk ``c`` in the output folder."""
    return os.path.join(CHUNK_DIR, f"chunk_{c:06d}.npz")


def finished_chunks(work, n: int, chunk: int, restart: bool = False) -> dict[int, dict]:
    """The chunk states in ``work``'s folder (:func:`chunk_file`), each read with the protocol's
    rules (another configuration's is refused, naming what changed; a damaged one named); with
    ``restart`` they are removed. Returns ``{c: arrays}``."""
    folder = work.path(CHUNK_DIR)
    os.makedirs(folder, exist_ok=True)
    found = {}
    for name in sorted(os.listdir(folder)):
        m = _CHUNK_FILE.match(name)
        if m is None:
            continue
        if restart:
            os.remove(os.path.join(folder, name))
            continue
        arrays = work.read_npz(os.path.join(CHUNK_DIR, name))
        c = int(m.group(1))
        if c < chunk_count(n, chunk):
            found[c] = arrays
    return found


def run_lanes(compiled, values, *shared, chunk: int | None, mesh, work=None, restart: bool = False,
              progress: bool = False, desc: str = "lanes") -> dict:
    """Every row of ``values`` (N, ...) through ``compiled(rows, *shared)`` (a jitted lanes
    function of a chunk placed on ``mesh``, e.g. :func:`over_lanes` inside :func:`on_devices`), in
    chunks of ``chunk`` rows (None: all at once; rounded up to a multiple of the mesh's devices),
    one chunk after another. With ``work`` (a :class:`jaxclear._checkpoint.Work` of the caller's
    folder; the caller holds its lock) every chunk is written as it finishes and a second call
    computes only the chunks not on disk (``restart``: none kept). Returns the outputs, a dict of
    (N, ...) host arrays, in the rows' order."""
    values = np.asarray(values)
    n, n_dev = len(values), mesh.devices.size
    chunk = round_chunk(n if chunk is None else chunk, n_dev)
    done = {} if work is None else finished_chunks(work, n, chunk, restart)
    n_chunks = chunk_count(n, chunk)
    todo = [c for c in range(n_chunks) if c not in done]

    def write(c, res):
        done[c] = res
        if work is not None:
            work.write_npz(chunk_file(c), res)

    run_chunks(todo, n_chunks, lambda c: compute_chunk(compiled, values, c, chunk, mesh, *shared), write,
               show=progress, desc=desc, resumed=bool(done) and bool(todo))
    parts = [done[c] for c in range(n_chunks)]
    return {k: np.concatenate([p[k] for p in parts], axis=0) for k in parts[0]}


__all__ = ["CHUNK_DIR", "HOST_THREADS_ENV", "MAX_HOST_THREADS", "ahead", "chunk_count", "chunk_file", "chunks_todo",
           "compute_chunk", "finished_chunks", "host_map", "host_rows", "host_threads", "lanes_one_by_one", "on_devices",
           "over_lanes", "padded_chunk", "round_chunk", "run_chunks", "run_lanes"]
