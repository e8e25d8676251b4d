"""The program store: jaxppo's compiled kernels kept on disk, beside JAX's
compilation cache, so that a new process loads them instead of tracing,
lowering and compiling them again.

JAX's persistent cache saves XLA's compilation only: a new process still
traces every program and lowers it to find the cache entry (0.1-0.5 s per
kernel on a 2-core CPU; most of a warm command's start). A stored kernel
(``stored``) is saved as its serialized executable
(``jax.experimental.serialize_executable``) under a key that covers
everything the program is made from:

* the function (module and qualified name) and the whole jaxppo package
  (the content of every source file, the size and time of every data
  file; hashed when jaxppo is imported, with the bytecode Python runs
  where it may not be the source's, and the store is turned off for the
  process if the files change afterwards (not the bytecode Python writes
  as it imports them), or a module-level value of jaxppo is set anew);
* the versions of Python, numpy, JAX and jaxlib; of each library whose
  code a program may trace (``TRACED_LIBRARIES``: equinox, optimistix,
  lineax, jnkepler, numpyro) the version and where its files are, with
  their sizes and modification times (an edited or another copy of
  jnkepler gave the old N-body program before); and JAX's options that
  change a trace (float64, matmul precision, dtype and rank promotion,
  NaN/Inf checks);
* the device (platform, kind, platform version, the CPU's instruction set);
* the static arguments and the structure of the others (equinox Modules'
  static fields included), each leaf's shape, dtype and weak type.

Only programs whose outputs are arrays in tuples, lists and dicts, and
whose custom calls are all LAPACK's, are stored (LAPACK is
loaded into the process before such a program runs): a host callback or
another library's kernel is an address in the process that compiled it.
Anything the key cannot describe exactly (a static value other than None,
bool, int, float, complex, str, bytes, numpy arrays and containers of
them and classes of jaxppo, JAX, equinox, optimistix, lineax and numpy; a
traced argument; several devices or processes; ``jax.disable_jit``)
runs the ordinary ``jax.jit`` path: the store only skips work, it never
changes a number. A function with closure cells is refused when it is
decorated (what it closes over would not be in the key).

Each stored program is compiled afresh, under a module name of its own
(an executable that JAX's persistent cache had loaded serialized without
its kernels), and a program read from the store runs once, to the end,
before it is trusted; one that fails is removed and the call takes the
jitted path.

The store is on where ``jaxppo.compilation_cache`` turned JAX's cache on
(every ``jaxppo`` command does): it is the cache folder's ``programs``
subfolder, kept to ``MAX_FILES`` files (the least recently written go).
Like JAX's own cache, it holds executables that are loaded and run: the
folder must be the user's own, not one others can write to.
"""

from __future__ import annotations

import concurrent.futures
import enum
import functools
import hashlib
import inspect
import itertools
import os
import pickle
import platform
import re
import sys
import threading
import time
from pathlib import Path

import jax
import numpy as np

__all__ = ["stored", "set_store", "store_folder", "custom_call_targets", "counts", "record_constants", "MAX_FILES",
           "TRACED_LIBRARIES", "library_stamp", "threads"]

MAX_FILES = 512

_state = {"folder": None}
_NONCE = itertools.count()
# a stored program's file: this format's tag, the sha256 of the rest, the rest
# (a damaged executable can kill the process that loads it: it is checked first)
_FORMAT = b"jaxppo-program-1\n"
# programs read from the store and compiled (and written) by this process
counts = {"loaded": 0, "compiled": 0, "failed": 0}
_lock = threading.Lock()


def set_store(folder) -> None:
    """Use ``folder`` for stored programs (None: off). ``compilation_cache``
    calls it with its cache folder's ``programs`` subfolder."""
    _state["folder"] = None if folder is None else Path(folder)


def store_folder() -> Path | None:
    """The folder in use, or None when the store is off."""
    return _state["folder"]


class _Unstable(Exception):
    """A value the key cannot describe exactly."""


def _stable(obj) -> bytes:
    """An exact byte description of a static value (raises _Unstable)."""
    if obj is None or isinstance(obj, (bool, int, float, complex, str, bytes)):
        return f"{type(obj).__name__}:{obj!r}".encode()
    if isinstance(obj, enum.Enum):
        return f"enum:{_known(type(obj))}.{obj.name}".encode()
    if isinstance(obj, (tuple, list)):
        return f"{type(obj).__name__}(".encode() + b",".join(_stable(v) for v in obj) + b")"
    if isinstance(obj, dict):
        items = sorted((_stable(k), _stable(v)) for k, v in obj.items())
        return b"dict(" + b",".join(k + b":" + v for k, v in items) + b")"
    if isinstance(obj, (frozenset, set)):
        return b"set(" + b",".join(sorted(_stable(v) for v in obj)) + b")"
    if isinstance(obj, (np.ndarray, np.generic)):
        a = np.ascontiguousarray(obj)
        if a.dtype.hasobject:
            raise _Unstable("object array")
        return f"ndarray:{a.dtype.str}:{a.shape}:".encode() + hashlib.sha256(a.tobytes()).hexdigest().encode()
    if isinstance(obj, type):
        return f"type:{_known(obj)}".encode()
    if type(obj).__name__ == "_Missing" and type(obj).__module__.startswith("equinox"):
        return b"equinox-missing"  # equinox's sentinel of a field without a value
    raise _Unstable(type(obj).__qualname__)


# packages whose code is in every key (jaxppo by its files, the others by
# their versions); a class from anywhere else (a user's subclass of Planet,
# say) could change without changing the key
_VERSIONED = ("jaxppo", "jax", "jaxlib", "equinox", "optimistix", "lineax", "numpy", "builtins")


def _known(cls: type) -> str:
    """``module.qualname`` of a class whose code the key covers."""
    if cls.__module__.split(".")[0] not in _VERSIONED:
        raise _Unstable(f"class {cls.__module__}.{cls.__qualname__} from outside the versioned packages")
    return f"{cls.__module__}.{cls.__qualname__}"


def _treedef_key(treedef) -> bytes:
    """The structure of the arguments, static fields included, exactly."""
    data = treedef.node_data()
    if data is None:  # a leaf
        return b"*"
    kind, aux = data
    children = b",".join(_treedef_key(c) for c in treedef.children())
    return _stable(kind) + b"[" + _stable(aux) + b"](" + children + b")"


def _package_hash(root=None) -> str:
    """sha256 of the installed jaxppo package (or the folder ``root``):
    every source file by its content, every other file (data) by its size
    and modification time. Bytecode counts only where Python would run it
    instead of its source's content (``_stale_bytecode``): the ``.pyc``
    files Python writes as it imports the package change no key (else a new
    install's second run found none of its first run's programs)."""
    root = Path(__file__).resolve().parents[1] if root is None else Path(root)
    h = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if not path.is_file() or "__pycache__" in path.parts or path.suffix in (".pyc", ".pyo"):
            continue
        h.update(str(path.relative_to(root)).encode() + b"\0")
        if path.suffix == ".py":
            h.update(path.read_bytes() + b"\0")
            stale = _stale_bytecode(path)
            if stale is not None:
                h.update(b"stale bytecode\0" + stale + b"\0")
        else:
            st = path.stat()
            h.update(f"{st.st_size}:{st.st_mtime_ns}\0".encode())
    return h.hexdigest()


def _stale_bytecode(source: Path) -> bytes | None:
    """The bytecode Python runs for ``source`` where it may not be the
    source's: a ``.pyc`` whose header matches the source's time (whole
    seconds) and size but which was written before the source's last
    change (an edit within the same second that kept the size), or an
    unchecked hash-based ``.pyc`` (never compared with its source). None
    where Python runs the source's own code."""
    import importlib.util

    try:
        cached = Path(importlib.util.cache_from_source(str(source)))
        with open(cached, "rb") as fh:
            head = fh.read(16)
        pyc, src = cached.stat(), source.stat()
    except (OSError, NotImplementedError, ValueError):
        return None
    if len(head) < 16 or head[:4] != importlib.util.MAGIC_NUMBER:
        return None  # not this Python's: it compiles the source
    flags = int.from_bytes(head[4:8], "little")
    if flags & 0b1:  # hash-based: checked against the source (bit 1) or never
        return None if flags & 0b10 else cached.read_bytes()
    stamp, size = int.from_bytes(head[8:12], "little"), int.from_bytes(head[12:16], "little")
    matches = stamp == (int(src.st_mtime) & 0xFFFFFFFF) and size == (src.st_size & 0xFFFFFFFF)
    return cached.read_bytes() if matches and pyc.st_mtime_ns < src.st_mtime_ns else None


def _cpu_flags() -> str:
    """The CPU's instruction-set flags (Linux), else the processor's name."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith(("flags", "Features")):
                    return hashlib.sha256(line.encode()).hexdigest()[:16]
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _stamp(root: Path) -> tuple:
    """(path, size, modification time) of every file of the package but its
    bytecode (which Python writes as it imports modules, the first time
    and for modules imported later)."""
    out = []
    for path in sorted(root.rglob("*")):
        if (path.is_file() and not path.name.endswith(".tmp") and "__pycache__" not in path.parts
                and path.suffix not in (".pyc", ".pyo")):
            st = path.stat()
            out.append((str(path), st.st_size, st.st_mtime_ns))
    return tuple(out)


_ROOT = Path(__file__).resolve().parents[1]
# the package as imported (jaxppo imports this module first): hashed now, so
# that an edit made later in this process's life cannot be taken for the
# code it runs; every read and write of the store checks it is unchanged
_PACKAGE = {"hash": _package_hash(_ROOT), "stamp": _stamp(_ROOT)}


_CONSTANTS: dict = {}


def _module_values() -> dict:
    """{(module, name): id} of the module-level values of every loaded
    jaxppo module (constants a kernel may read while it is traced)."""
    out = {}
    for name, module in list(sys.modules.items()):
        if module is not None and (name == "jaxppo" or name.startswith("jaxppo.")):
            for key, value in list(vars(module).items()):
                if not key.startswith("__"):
                    out[(name, key)] = id(value)
    return out


def record_constants() -> None:
    """Remember the module-level values of jaxppo's loaded modules (jaxppo's
    ``__init__`` calls it last): a value set later (``INNER_MARGIN = 50``)
    turns the store off for the process, as an edited file does."""
    _CONSTANTS.update(_module_values())


def _unchanged() -> bool:
    """Whether the package's files are still those hashed at import and its
    modules' values those recorded (modules imported since are recorded
    now); if not, the store is turned off for this process (its code may
    differ from the files, or read another value)."""
    now = _module_values()
    moved = any(now.get(k, v) != v for k, v in _CONSTANTS.items())
    for k, v in now.items():
        _CONSTANTS.setdefault(k, v)
    if moved or _stamp(_ROOT) != _PACKAGE["stamp"]:
        _state["folder"] = None
        return False
    return True


# The libraries whose Python code a stored program may trace: equinox's
# modules, optimistix's and lineax's solvers, jnkepler's N-body integrator
# (imported where a system first integrates: after the key's first use),
# numpyro's distributions. A program compiled with one copy of them must not
# be loaded where another is imported (an upgrade, an edit of an editable
# install, another copy first on sys.path).
TRACED_LIBRARIES = ("equinox", "optimistix", "lineax", "jnkepler", "numpyro")


def library_stamp(name: str) -> str:
    """The version of library ``name`` and a digest of where its Python
    files are, with their sizes and modification times (the copy an import
    finds now: ``importlib.util.find_spec``, which imports nothing);
    ``"<name>=none"`` where it is not installed."""
    import importlib.util
    from importlib import metadata

    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        spec = None
    if spec is None:
        return f"{name}=none"
    try:
        version = metadata.version(name)
    except metadata.PackageNotFoundError:
        version = "unknown"
    roots = [Path(p) for p in (spec.submodule_search_locations or [])] or [Path(str(spec.origin))]
    h = hashlib.sha256()
    for root in roots:
        for path in (sorted(root.rglob("*.py")) if root.is_dir() else [root]):
            try:
                st = path.stat()
            except OSError:
                continue
            h.update(f"{path}\0{st.st_size}\0{st.st_mtime_ns}\0".encode())
    return f"{name}={version}:{h.hexdigest()}"


@functools.lru_cache(maxsize=None)
def _environment(options: bytes) -> bytes:
    """What every key shares: package, versions (with ``library_stamp``
    of each of ``TRACED_LIBRARIES``), device, XLA's flags, JAX's options
    (``options``, encoded)."""
    from importlib import metadata

    versions = [sys.version, np.__version__, jax.__version__]
    try:
        versions.append(f"jaxlib={metadata.version('jaxlib')}")
    except metadata.PackageNotFoundError:
        versions.append("jaxlib=none")
    versions += [library_stamp(name) for name in TRACED_LIBRARIES]
    dev = jax.devices()[0]
    device = [dev.platform, getattr(dev, "device_kind", ""), dev.client.platform_version, _cpu_flags()]
    flags = [os.environ.get(v, "") for v in ("XLA_FLAGS", "LIBTPU_INIT_ARGS", "NEURON_CC_FLAGS")]
    return _stable((_PACKAGE["hash"], versions, device, flags)) + options


# JAX's options, every one of them (their values where the call is made,
# context managers included), but the choice of platform: the device the
# program runs on is in the key itself
_NOT_OPTIONS = ("jax_platforms", "jax_platform_name")


def _options() -> tuple:
    """The values of all of JAX's options at this call."""
    return tuple((name, getattr(jax.config, name, None)) for name in sorted(jax.config.values)
                 if name not in _NOT_OPTIONS)


# the last options seen and their encoding (encoding them took 1 ms of each call)
_OPTIONS_SEEN = [(None, b"")]


def _options_key() -> bytes:
    """``_options()`` encoded (``_stable``); encoded again only when an
    option's value changed since the last call."""
    options = _options()
    seen, encoded = _OPTIONS_SEEN[0]
    try:
        same = bool(options == seen)
    except Exception:  # noqa: BLE001 - a value that does not compare: encoded anew
        same = False
    if not same:
        encoded = _stable(options)
        _OPTIONS_SEEN[0] = (options, encoded)
    return encoded


def _usable() -> bool:
    """One device, one process, jit enabled, no NaN/Inf checks (jit re-runs
    a failing program op by op to name the operation; a compiled one
    cannot): where a stored program is what jit would run."""
    return (jax.process_count() == 1 and len(jax.devices()) == 1 and not jax.config.jax_disable_jit
            and not jax.config.jax_debug_nans and not jax.config.jax_debug_infs)


def _aval(leaf) -> tuple:
    """(shape, dtype, weak type) of an array argument, as the key has it."""
    try:
        aval = jax.typeof(leaf)
    except TypeError as err:  # a big-endian numpy array: jit converts it, the key cannot
        raise _Unstable(str(err)) from None
    return aval.shape, str(aval.dtype), bool(getattr(aval, "weak_type", False))


class _Stored:
    """A jitted function whose compiled programs are kept in the store."""

    def __init__(self, fn, static_argnames, filtered=False):
        if fn.__closure__:
            raise ValueError(f"stored: {fn.__qualname__} has closure cells ({fn.__code__.co_freevars}); "
                             "what it closes over would not be in the program's key")
        if "<" in fn.__qualname__:
            raise ValueError(f"stored: {fn.__qualname__} is not a module-level function; its name would not "
                             "tell it from another one of the same name")
        self._fn = fn
        self._sig = inspect.signature(fn)
        self._static = tuple(static_argnames)
        self._filtered = filtered
        if filtered:
            import equinox as eqx

            self._jit = eqx.filter_jit(fn)
        else:
            self._jit = jax.jit(fn, static_argnames=self._static)
        self._name = f"{fn.__module__}.{fn.__qualname__}"
        if fn.__module__.split(".")[0] != "jaxppo":  # not in the package hash: its file's content is
            try:
                self._name += ":" + hashlib.sha256(Path(inspect.getsourcefile(fn)).read_bytes()).hexdigest()
            except (OSError, TypeError):  # no file (python -c, a notebook): never stored
                self._name = None
        self._loaded = {}
        self._pending = {}  # key: (the Future of a program ``precompile`` compiles or reads, whether it reads it)
        functools.update_wrapper(self, fn)

    def __getattr__(self, name):  # lower, trace, eval_shape, ... of the jitted function
        return getattr(self._jit, name)

    def _split(self, leaves):
        """(which leaves are traced, the others): arrays are traced; with
        ``filtered`` (as ``equinox.filter_jit``) every other leaf is
        static, else Python numbers are traced and nothing else may occur."""
        traced, fixed = [], []
        for leaf in leaves:
            if isinstance(leaf, jax.core.Tracer):
                raise _Unstable("traced")
            array = isinstance(leaf, (jax.Array, np.ndarray, np.generic))
            if not array and not self._filtered and not isinstance(leaf, (bool, int, float, complex)):
                raise _Unstable("not an array")
            traced.append(array or not self._filtered)
            fixed.append(None if traced[-1] else leaf)
        return traced, tuple(fixed)

    def _bind(self, args, kwargs) -> tuple:
        """(static arguments, the others) of a call, by name, defaults
        filled in."""
        bound = self._sig.bind(*args, **kwargs)
        bound.apply_defaults()
        statics = {k: v for k, v in bound.arguments.items() if k in self._static}
        return statics, {k: v for k, v in bound.arguments.items() if k not in self._static}

    def _plan(self, args, kwargs):
        """(key, folder, traced inputs, (treedef, traced, fixed), statics)
        of this call, or None where the store cannot serve it (off, not
        usable, or an argument the key cannot describe exactly)."""
        folder = _state["folder"]
        if folder is None or self._name is None or not _usable():
            return None
        statics, dynamic = self._bind(args, kwargs)
        leaves, treedef = jax.tree_util.tree_flatten(dynamic)
        try:
            traced, fixed = self._split(leaves)
            inputs = [leaf for leaf, t in zip(leaves, traced) if t]
            avals = [_aval(leaf) for leaf in inputs]
            key = hashlib.sha256(
                _environment(_options_key()) + _stable(self._name)
                + _stable(statics) + _treedef_key(treedef) + _stable(fixed) + _stable(avals)).hexdigest()
        except _Unstable:
            return None
        return key, folder, inputs, (treedef, traced, fixed), statics

    def __call__(self, *args, **kwargs):
        plan = self._plan(args, kwargs)
        if plan is None:
            return self._jit(*args, **kwargs)
        key, folder, inputs, structure, statics = plan
        compiled = self._loaded.get(key)
        if compiled is not None:
            return compiled(*inputs)
        pending, from_file = self._pending.pop(key, (None, False))
        if pending is not None:  # compiled or read by ``precompile``'s thread (the same key: the same program)
            try:
                compiled = pending.result()
            except Exception:  # noqa: BLE001 - compiled again below, where the error shows as jit's
                compiled = None
            if compiled is not None and not from_file:
                self._loaded[key] = compiled
                return compiled(*inputs)
        if not _unchanged():
            return self._jit(*args, **kwargs)
        if compiled is None:
            compiled, from_file = self._load_or_compile(folder, key, inputs, structure, statics)
        if not from_file:
            self._loaded[key] = compiled
            return compiled(*inputs)
        try:  # a program read from the store runs once, to the end, before it is trusted
            out = jax.block_until_ready(compiled(*inputs))
        except Exception:  # noqa: BLE001 - it does not run here: removed, and the jitted path instead
            try:
                (folder / f"{key}.exe").unlink(missing_ok=True)
            except OSError:  # a read-only store
                pass
            counts["failed"] += 1
            return self._jit(*args, **kwargs)
        self._loaded[key] = compiled
        return out

    def precompile(self, *args, **kwargs) -> None:
        """Compile the program of a call with these arguments' shapes in a
        thread of its own, traced and lowered here: XLA's compilation runs
        without Python's lock, beside what this thread does next (the
        fit's Levenberg-Marquardt program traces while its minimum check's
        program compiles). Where the store holds the program, the thread
        reads it instead (deserializing runs without Python's lock too:
        0.1 s of a new process's fit, beside the loading of its
        Levenberg-Marquardt program); the call then runs it once before
        trusting it, as any program read from the store. The call with
        those shapes takes that program (waiting for it if need be).
        Nothing happens where the store is off or cannot serve the call,
        or the program is loaded or pending already."""
        plan = self._plan(args, kwargs)
        if plan is None:
            return
        key, folder, inputs, structure, statics = plan
        path = folder / f"{key}.exe"
        if key in self._loaded or key in self._pending or not _unchanged():
            return
        from_file = path.exists()
        lowered = None if from_file else self._lower(key, inputs, structure, statics)
        pending = concurrent.futures.Future()
        self._pending[key] = (pending, from_file)

        def work():
            try:
                pending.set_result(_read(path) if from_file else self._finish(folder, path, lowered)[0])
            except BaseException as err:  # noqa: BLE001 - the call compiles it again
                pending.set_exception(err)

        # not a daemon: a process that ends meanwhile waits for it (a compiler
        # stopped halfway through at exit can crash the interpreter)
        threading.Thread(target=work, name=f"jaxppo-precompile-{self._fn.__qualname__}").start()

    def map_to_host(self, calls) -> list:
        """``[self(*args) for args in calls]`` with every output a numpy
        array, the calls run ``threads()`` at a time: a
        2-core CPU runs two calls of a program like the fit's residuals in
        2/3 of the time it runs them one by one (XLA keeps the second core
        busy a quarter of the time). Each call's program is chosen here,
        as ``__call__`` does (JAX's options can be set per thread: the
        threads only run it); where the store cannot serve a call, all run
        here, one by one."""
        host = functools.partial(jax.tree_util.tree_map, np.asarray)
        calls = [tuple(args) for args in calls]
        plans = [self._plan(calls[0], {})] if calls else []
        plans += [self._plan_like(args, calls[0], plans[0]) for args in calls[1:]]
        first = []
        if plans and plans[0] is not None and plans[0][0] not in self._loaded:
            first = [host(self(*calls[0]))]  # read from the store or compiled, here
        jobs = [None if plan is None else (self._loaded.get(plan[0]), plan[2]) for plan in plans[len(first):]]
        if threads() < 2 or len(jobs) < 2 or any(job is None or job[0] is None for job in jobs):
            return first + [host(self(*args)) for args in calls[len(first):]]
        # numbers and numpy arrays become JAX arrays here, under this thread's options (dtype)
        jobs = [(compiled, [x if isinstance(x, jax.Array) else jax.device_put(x) for x in inputs])
                for compiled, inputs in jobs]
        return first + list(_pool().map(lambda job: host(job[0](*job[1])), jobs))

    def _plan_like(self, args, first, plan):
        """``_plan(args)``, from ``plan`` (the plan of the arguments
        ``first``) where each of ``args`` is the very object of ``first``
        or an array of the same shape, dtype and weak type: the same
        program (encoding the key took 1.6 ms a call)."""
        if plan is None or len(args) != len(first):
            return self._plan(args, {})
        for a, b in zip(args, first):
            if a is b:
                continue
            arrays = (jax.Array, np.ndarray)
            try:
                same = (isinstance(a, arrays) and isinstance(b, arrays) and not isinstance(a, jax.core.Tracer)
                        and _aval(a) == _aval(b))
            except _Unstable:
                same = False
            if not same:
                return self._plan(args, {})
        key, folder, _, structure, statics = plan
        leaves = jax.tree_util.tree_leaves(self._bind(args, {})[1])
        return key, folder, [leaf for leaf, t in zip(leaves, structure[1]) if t], structure, statics

    def _load_or_compile(self, folder: Path, key: str, inputs, structure, statics):
        """(the program of ``key``, whether it was read from the store): read
        from the store, else compiled (and written there). A file that does
        not load is compiled again."""
        path = folder / f"{key}.exe"
        compiled = _read(path)
        if compiled is not None:
            return compiled, True
        return self._finish(folder, path, self._lower(key, inputs, structure, statics))

    def _lower(self, key: str, inputs, structure, statics):
        """The program of ``key`` traced and lowered (not compiled)."""
        fn = self._fn
        treedef, traced, fixed = structure

        def flat(*values):
            it = iter(values)
            leaves = [next(it) if t else f for t, f in zip(traced, fixed)]
            return fn(**jax.tree_util.tree_unflatten(treedef, leaves), **statics)

        # a module name of its own: XLA compiles this program afresh. From
        # JAX's persistent cache (the same program compiled before: another
        # planet's name, a store file lost) came an executable whose
        # serialization lacked its kernels ("Function ... not found" when
        # loaded in a new process)
        flat.__name__ = flat.__qualname__ = f"stored_{key[:20]}_{os.getpid()}_{next(_NONCE)}"
        return jax.jit(flat).lower(*inputs)

    def _finish(self, folder: Path, path: Path, lowered):
        """(``lowered`` compiled, False), written to the store at ``path``
        where it can be loaded in another process."""
        from jax.experimental import serialize_executable as se

        targets = custom_call_targets(lowered.as_text())
        compiled = lowered.compile()
        with _lock:
            counts["compiled"] += 1
        if any(not t.startswith("lapack_") for t in targets):
            return compiled, False  # a host callback or another library's kernel: never reloaded
        if not _builtin(compiled.out_tree):
            return compiled, False  # outputs with classes of their own (their sentinels do not survive pickling)
        try:
            body = pickle.dumps((sorted(targets), *se.serialize(compiled)))
            blob = _FORMAT + hashlib.sha256(body).digest() + body
        except Exception:  # noqa: BLE001 - not serializable (constants, custom outputs): in memory only
            return compiled, False
        _write(folder, path, blob)
        return compiled, False


def _read(path: Path):
    """The program stored at ``path``, deserialized (LAPACK loaded into the
    process meanwhile where it calls LAPACK: ``_prepare_lapack``, 0.1 s,
    beside the 0.3 s of deserializing the fit's Levenberg-Marquardt
    program, which runs without Python's lock); None where there is none,
    or the file is damaged or foreign (then compiled again)."""
    from jax.experimental import serialize_executable as se

    try:
        with open(path, "rb") as fh:
            blob = fh.read()
        head, digest, body = blob[:len(_FORMAT)], blob[len(_FORMAT):len(_FORMAT) + 32], blob[len(_FORMAT) + 32:]
        if head != _FORMAT or hashlib.sha256(body).digest() != digest:
            raise ValueError("not a stored program, or a damaged one")  # never handed to the loader
        targets, payload, in_tree, out_tree = pickle.loads(body)
        if targets and _prepare_lapack.cache_info().currsize == 0:
            # LAPACK before the program runs (not before it loads): both at once
            loading = _loader().submit(se.deserialize_and_load, payload, in_tree, out_tree)
            _prepare_lapack()
            compiled = loading.result()
        else:
            compiled = se.deserialize_and_load(payload, in_tree, out_tree)
    except Exception:  # noqa: BLE001 - none, a damaged or a foreign file: compile again
        return None
    with _lock:
        counts["loaded"] += 1
    return compiled


@functools.lru_cache(maxsize=None)
def _loader() -> concurrent.futures.ThreadPoolExecutor:
    """The thread that deserializes a program while ``_read``'s loads LAPACK."""
    return concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="jaxppo-load")


def threads() -> int:
    """How many calls ``map_to_host`` runs at once: the CPUs this process
    may use, at most 4 (XLA's own threads use the others)."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, 4))


@functools.lru_cache(maxsize=None)
def _pool() -> concurrent.futures.ThreadPoolExecutor:
    """The threads of ``map_to_host`` (started at its first use)."""
    return concurrent.futures.ThreadPoolExecutor(threads(), thread_name_prefix="jaxppo-program")


def _builtin(treedef) -> bool:
    """Whether a pytree structure holds only tuples, lists, dicts and None."""
    data = treedef.node_data()
    if data is None:
        return True
    return data[0] in (tuple, list, dict, type(None)) and all(_builtin(c) for c in treedef.children())


def custom_call_targets(text: str) -> set:
    """The custom-call targets of a lowered program's text (StableHLO)."""
    return set(re.findall(r"custom_call\s*@([\w.$-]+)", text)) | set(re.findall(r'call_target_name\s*=\s*"([^"]+)"', text))


@functools.lru_cache(maxsize=None)
def _prepare_lapack() -> None:
    """Load LAPACK into this process before a stored program that calls it
    runs (jaxlib does so when it lowers a LAPACK call; a stored program is
    not lowered, and would call an empty LAPACK table). jaxlib's
    ``lapack.prepare_lapack_call`` is what that lowering calls (0.08 s);
    with a jaxlib that lacks it, a LAPACK call is lowered (0.19 s). One
    thread at a time (``precompile``'s and the caller's may both read a
    program that calls LAPACK)."""
    with _LAPACK_LOCK:
        _load_lapack()


_LAPACK_LOCK = threading.Lock()


def _load_lapack() -> None:
    """``_prepare_lapack``'s work."""
    try:
        from jaxlib import lapack

        lapack.prepare_lapack_call("geqrf", np.dtype("float64"))
        return
    except Exception:  # noqa: BLE001 - another jaxlib: the lowering loads it
        pass
    import jax.numpy as jnp

    jax.jit(jnp.linalg.qr).lower(jnp.ones((2, 2)))


def _write(folder: Path, path: Path, blob: bytes) -> None:
    """Write one program atomically; keep at most MAX_FILES in the store."""
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as fh:
            fh.write(blob)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError:  # an unwritable or full store only costs the compilation next time
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        return
    try:
        with _lock:
            now = time.time()
            stale = [p for p in folder.glob("*.tmp") if now - p.stat().st_mtime > 3600]  # an interrupted write
            files = sorted(folder.glob("*.exe"), key=lambda p: p.stat().st_mtime)
            for old in stale + files[:max(len(files) - MAX_FILES, 0)]:
                old.unlink(missing_ok=True)
    except OSError:
        pass


def stored(fn=None, *, static_argnames=(), filtered=False):
    """``jax.jit`` (or ``equinox.filter_jit``) whose compiled programs are also kept in the program store.

    Parameters
    ----------
    fn : callable
        A module-level function (no closure cells) of arrays and pytrees.
    static_argnames : tuple of str, optional
        Its static arguments, as for ``jax.jit``.
    filtered : bool, optional
        As ``equinox.filter_jit``: array leaves are traced, every other
        leaf is static (default False: ``jax.jit``).

    Returns
    -------
    callable
        Called like ``jax.jit(fn, static_argnames=...)``, with the same
        results; ``lower`` and the other attributes are the jitted
        function's.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> from jaxppo.model._programs import stored
    >>> @stored(static_argnames=("power",))
    ... def moment(x, power):
    ...     return jnp.mean(x ** power)
    >>> float(moment(jnp.arange(4.0), power=2))
    3.5
    """
    if fn is None:
        return functools.partial(stored, static_argnames=static_argnames, filtered=filtered)
    return _Stored(fn, static_argnames, filtered)
