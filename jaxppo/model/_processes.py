"""Several JAX processes (``jax.distributed.initialize``: one per host or per
GPU, one global device mesh): which process writes files, and the state
that every process must share so that all of them run the same compiled
collectives.

The kernels already place their frames over every process's devices and
gather the results (``._plan.to_host``), so each process holds the same
numbers. Files are another matter: every process writing the same folder
races (one process's rename removes the other's temporary file), and a
process that resumes from a file another process is rewriting computes a
different set of blocks and waits forever in a collective the others never
enter. So process 0 alone reads and writes a run's folder; what it read
(the finished blocks of a resumed run) reaches the other processes through
``share``; ``barrier`` holds every process until process 0 has written.
With one process every function here is a no-op.
"""

from __future__ import annotations

import json

import jax
import numpy as np

__all__ = ["is_writer", "share", "read_once", "on_writer", "barrier", "process_info", "start_from_environment"]


def is_writer() -> bool:
    """True in the process that reads and writes files: process 0 (the only
    one without ``jax.distributed``)."""
    return jax.process_index() == 0


def process_info() -> dict:
    """{"devices": the global device count, "processes": the process count}:
    what a run's summary records about where it ran."""
    return {"devices": int(jax.device_count()), "processes": int(jax.process_count())}


def share(obj):
    """Process 0's ``obj`` (anything ``json`` writes and reads back
    unchanged: dicts with string keys, lists, strings, numbers, None) in
    every process; the other processes' ``obj`` is ignored. Floats travel
    as their shortest repr, so they arrive bit for bit."""
    if jax.process_count() == 1:
        return obj
    from jax.experimental import multihost_utils

    data = np.frombuffer(json.dumps(obj).encode(), dtype=np.uint8) if is_writer() else np.zeros(0, np.uint8)
    n = int(multihost_utils.broadcast_one_to_all(np.int32(data.size)))
    buf = np.zeros(n, np.uint8)
    if is_writer():
        buf[:] = data
    buf = np.asarray(multihost_utils.broadcast_one_to_all(buf), dtype=np.uint8)
    return json.loads(buf.tobytes().decode())


def _on_process_0(fn):
    """(fn(), None) in process 0, (None, "Type: message") there if it
    raised, (None, None) elsewhere: any error, so that every process can
    hear of it and none is left waiting."""
    if not is_writer():
        return None, None
    try:
        return fn(), None
    except Exception as err:  # noqa: BLE001 - any error: every process must hear of it, none may wait
        return None, f"{type(err).__name__}: {err}"


def read_once(read, what: str, encode=lambda v: v, decode=lambda v: v):
    """``read()`` (a run's folder: its progress, its stored results) called
    by process 0 alone; every other process gets ``decode(share(encode(
    value)))`` (``encode`` makes the value JSON-able). An error there
    (any exception) stops every process: with one process it
    is raised as it is; with several, each raises a ``ValueError`` naming
    process 0 and ``what`` (none is left waiting in a collective the
    others never enter)."""
    if jax.process_count() == 1:
        return read()
    value, error = _on_process_0(read)
    got = share({"value": None if error is not None or not is_writer() else encode(value), "error": error})
    if got["error"] is not None:
        raise ValueError(f"process 0 could not read {what}: {got['error']}")
    return value if is_writer() else decode(got["value"])


_writing: list = []  # the on_writer calls under way in this process


def on_writer(what: str, fn):
    """``fn()`` (writing a run's files) in process 0 alone; its value there,
    None elsewhere. With several processes every process waits for it (a
    barrier) and an error there (a full disk, a folder that cannot be
    written) is raised in every process as a ``ValueError`` naming
    ``what``: none is left waiting in a collective process 0 never
    enters. With one process ``fn()`` runs and raises as it is; so does a
    call inside another ``on_writer``'s ``fn`` (process 0 alone runs it;
    the outer call shares the outcome)."""
    if jax.process_count() == 1 or _writing:
        return fn()  # one process, or inside another on_writer (process 0 alone is here; the outer one shares)
    _writing.append(what)
    try:
        value, error = _on_process_0(fn)
    finally:
        _writing.pop()
    error = share(error)
    if error is not None:
        raise ValueError(f"process 0 failed while {what}: {error}")
    return value


def barrier(name: str) -> None:
    """Wait until every process reaches the barrier ``name`` (a no-op with
    one process)."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)


def start_from_environment() -> bool:
    """Join several JAX processes as the environment says, before any JAX
    computation; True when it did. JAXPPO_DISTRIBUTED=auto:
    ``jax.distributed.initialize()`` finds the processes itself (SLURM,
    Open MPI); JAXPPO_DISTRIBUTED=N: process JAXPPO_PROCESS_ID of N meets
    the others at JAX_COORDINATOR_ADDRESS (host:port of process 0); unset
    or empty: one process, nothing done. CPU collectives use gloo."""
    import os

    how = os.environ.get("JAXPPO_DISTRIBUTED", "").strip()
    if not how:
        return False
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    if how == "auto":
        jax.distributed.initialize()
        return True
    address, pid_text = os.environ.get("JAX_COORDINATOR_ADDRESS"), os.environ.get("JAXPPO_PROCESS_ID", "")
    try:
        n, pid = int(how), int(pid_text)
    except ValueError:
        raise ValueError(f"JAXPPO_DISTRIBUTED={how!r}, JAXPPO_PROCESS_ID={pid_text!r}: give 'auto', or a number of "
                         "processes N >= 1 with JAXPPO_PROCESS_ID in 0..N-1 and JAX_COORDINATOR_ADDRESS=host:port") from None
    if n < 1 or not 0 <= pid < n or not address:
        raise ValueError(f"JAXPPO_DISTRIBUTED={n}, JAXPPO_PROCESS_ID={pid}, JAX_COORDINATOR_ADDRESS={address!r}: "
                         "need N >= 1, 0 <= id < N and the coordinator's host:port")
    jax.distributed.initialize(num_processes=n, process_id=pid)
    return True
