"""A second process that draws while this one computes.

After the scan, ``jaxppo scan`` draws five figures (matplotlib: about half
of a warm run's seconds) and fits the PPO-or-spot alternatives (JAX). The
two do not depend on each other, so the command hands the figures with
light curves (Figs. 4 and 6, most of the drawing) to a process it started
when it began (its imports and JAX set-up overlap the scan), fits
meanwhile and then draws the other three itself. The figures are the same files, byte for byte, as
drawn in one process (``tests/obliquity/test_worker.py``).

The drawing process evaluates the figures' light curves on the CPU (where
a GPU holds this process's memory, the drawing one must not take it) with
the command's float64 and compilation cache (``setup``). It is a fresh
interpreter fed pickled jobs through a pipe (forking a process that runs
JAX's threads can deadlock; multiprocessing's "spawn" would run the
caller's script again in it). Any failure to start it, or its
death, makes the job run here instead: the outputs never depend on it.
JAXPPO_DRAW_PROCESS=0 switches it off; it is never used under several JAX
processes (there every process computes the curves' collectives).
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import warnings

__all__ = ["Drawer", "serve"]


def serve(parent: int, package: str) -> None:
    """The drawing process's main (``python -c "...; serve(...)"``, which
    first ignores Ctrl-C: the command handles it and ends this process, and
    gives this process the command's ``sys.path``): reads pickled messages
    from stdin, answers on what was stdout (its own printing goes to
    stderr). It stops at once where its jaxppo is not the command's
    (``package``: the command's ``jaxppo/__init__.py``), and when the
    command (process id ``parent``) is gone. The first message is the
    set-up function (the command's float64 and compilation cache); then
    jobs ``(fn, args)`` until ``None`` or the end of the pipe, each answered
    ("ok", value, warnings) or ("error", exception, warnings) (warnings:
    the (message, category) pairs the job raised)."""
    import threading
    import time

    import jaxppo

    if os.path.abspath(jaxppo.__file__) != package:  # another copy of jaxppo: the command draws itself
        return

    def watch():  # the command killed (not by Ctrl-C): draw nothing more into its folder
        while os.getppid() == parent:
            time.sleep(0.2)
        os._exit(0)

    threading.Thread(target=watch, daemon=True).start()
    rx, tx = sys.stdin.buffer, os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # a print of a library cannot corrupt the answers
    setup = pickle.load(rx)
    if setup is not None:
        setup()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401 - imported while the scan runs, not when the figures are due

    while True:
        try:
            job = pickle.load(rx)
        except EOFError:  # the command ended
            return
        if job is None:
            return
        try:
            tx.write(_answer(*job))
            tx.flush()
        except OSError:  # the command is gone
            return


def _answer(fn, args) -> bytes:
    """``fn(*args)`` run, its answer pickled: ("ok", value, warnings) or
    ("error", exception, warnings); what cannot travel (or be rebuilt by
    the command) travels as text."""
    with warnings.catch_warnings(record=True) as caught:  # said again by the command, as its own
        warnings.simplefilter("always")
        try:
            answer = ("ok", fn(*args))
        except Exception as err:  # noqa: BLE001 - sent back and raised there, as if run there
            answer = ("error", err)
    said = [(str(w.message), w.category if _travels(w.category) else UserWarning) for w in caught]
    try:
        data = pickle.dumps((*answer, said))
        pickle.loads(data)  # what the command will read: an exception class that cannot be rebuilt fails here
    except Exception as err:  # noqa: BLE001 - an answer that does not travel: its text does
        what = answer[1] if answer[0] == "error" else err
        data = pickle.dumps(("error", RuntimeError(f"{type(what).__name__}: {what}"), said))
    return data


def _travels(obj) -> bool:
    """Whether ``obj`` pickles and unpickles."""
    try:
        pickle.loads(pickle.dumps(obj))
        return True
    except Exception:  # noqa: BLE001 - any failure: it does not travel
        return False


class Drawer:
    """The drawing process of one command (see the module docstring):
    ``run(fn, *args)`` starts ``fn(*args)`` there (or here, without one)
    and returns a callable that waits for its value; ``close()`` ends the
    process. Use as a context manager."""

    def __init__(self, setup=None, use: bool = True):
        self._proc = None
        if not use or os.environ.get("JAXPPO_DRAW_PROCESS", "1") == "0":
            return
        # a fresh interpreter, not multiprocessing: forking JAX's threads can
        # deadlock, and "spawn" would run the caller's own script again
        env = dict(os.environ, JAX_PLATFORMS="cpu")  # the figures' curves on the CPU: a GPU stays this process's
        import jaxppo

        code = ("import signal, sys; signal.signal(signal.SIGINT, signal.SIG_IGN); "
                f"sys.path[:] = {sys.path!r}; "  # the command's jaxppo, however it found it (checked there too)
                "from jaxppo.obliquity._worker import serve; "
                f"serve({os.getpid()}, {os.path.abspath(jaxppo.__file__)!r})")
        self._jobs = 0
        try:
            self._proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          env=env)
            self._send(setup)
        except Exception:  # noqa: BLE001 - no second process (a sandbox, no executable): draw here
            self._stop()

    def _send(self, obj) -> None:
        self._proc.stdin.write(pickle.dumps(obj))
        self._proc.stdin.flush()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def separate(self) -> bool:
        """Whether jobs run in the drawing process (else in this one)."""
        return self._proc is not None

    def run(self, fn, *args):
        """Start ``fn(*args)``; return a callable that waits and returns
        its value (or raises its exception). ``fn`` and ``args`` must
        pickle (a module-level function, plain data)."""
        if self._proc is None:
            return _done(fn, args)
        try:
            self._send((fn, args))
            self._jobs += 1
        except Exception:  # noqa: BLE001 - the process is gone: run here
            self._stop()
            return _done(fn, args)

        def wait():
            try:
                kind, value, said = pickle.load(self._proc.stdout)
            except (EOFError, OSError, pickle.UnpicklingError):  # the process died (killed, out of memory): here
                self._stop()
                return fn(*args)
            for message, category in said:
                warnings.warn(message, category, stacklevel=2)
            if kind == "error":
                raise value
            return value

        return wait

    def close(self) -> None:
        """End the drawing process (at once: any job's answer has been read
        or is not wanted)."""
        self._stop()

    def _stop(self) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()  # the end of the pipe: the process returns
        except Exception:  # noqa: BLE001 - already gone
            pass
        try:
            proc.wait(timeout=0.5 if self._jobs else 0)  # never used (a finished scan): no need to wait
        except subprocess.TimeoutExpired:  # still importing, or drawing a job nobody waits for
            proc.kill()
            proc.wait()
        proc.stdout.close()


def _done(fn, args):
    """Run ``fn(*args)`` here, now; its value behind the same waiting
    callable as a job of the drawing process."""
    value = fn(*args)
    return lambda: value
