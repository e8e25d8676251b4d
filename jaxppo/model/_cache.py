"""JAX's persistent compilation cache for jaxppo's programs: a second run
(a new process) loads what the first compiled instead of compiling it
again. Every ``jaxppo`` command turns it on; a Python user turns it on
with ``jaxppo.compilation_cache()`` before the first computation."""

from __future__ import annotations

import os

import jax

from ._programs import set_store

__all__ = ["compilation_cache"]


def compilation_cache(path=None) -> str | None:
    """Turn on JAX's persistent compilation cache for this process.

    Compiled programs are written to the folder and read back by later
    processes (the same program: the same code, shapes, options, JAX and
    hardware), so a second run skips XLA's compilation. jaxppo's own
    kernels go further: their executables are kept in the folder's
    ``programs`` subfolder under a key of the package's code, the versions,
    the device, the options and the arguments' structure and shapes, so a
    second run skips their tracing too. Results do not depend on either. It sets JAX's process-wide options
    (``jax_compilation_cache_dir``, and caches every program however
    small or quick to compile), so it is a call, not a side effect of
    importing jaxppo.

    Parameters
    ----------
    path : str or os.PathLike, optional
        The cache folder (``~`` expanded, made absolute). None (default): ``$JAXPPO_CACHE_DIR``, else
        ``$XDG_CACHE_HOME/jaxppo/jax``, else ``~/.cache/jaxppo/jax`` (what
        the ``jaxppo`` commands use). It is created if missing.

    Returns
    -------
    str or None
        The folder in use (a later call with another folder moves the
        cache there); None when ``JAXPPO_CACHE=0`` switches the cache
        off, or the folder cannot be made (then programs are only compiled
        again, nothing fails).

    Examples
    --------
    >>> import jaxppo as jp
    >>> folder = jp.compilation_cache()  # before the first computation
    >>> folder is None or folder.endswith("jax")  # None where JAXPPO_CACHE=0
    True
    """
    if os.environ.get("JAXPPO_CACHE", "1") == "0":
        return None
    if path is None:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        path = os.environ.get("JAXPPO_CACHE_DIR") or os.path.join(base, "jaxppo", "jax")
    path = os.path.abspath(os.path.expanduser(os.fsdecode(path)))
    try:
        os.makedirs(path, exist_ok=True)
    except OSError:
        return None  # an unwritable cache folder only costs the recompilation
    before = jax.config.jax_compilation_cache_dir
    jax.config.update("jax_compilation_cache_dir", path)
    if before is not None and before != path:  # JAX opened the first folder for good: reopen
        from jax.experimental.compilation_cache import compilation_cache as jax_cache

        jax_cache.reset_cache()
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    set_store(os.path.join(path, "programs"))
    return path
