"""The program store (jaxppo.model._programs): stored kernels give the jitted
function's numbers, a new process loads them instead of compiling, and the
key changes with everything a program is made from."""

import concurrent.futures
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo.model import _programs
from jaxppo.model._programs import counts, custom_call_targets, set_store, stored
from jaxppo.model._terms import exact_frames


@pytest.fixture
def store(tmp_path):
    """The store on in a fresh folder for one test, off afterwards."""
    folder = tmp_path / "programs"
    set_store(folder)
    yield folder
    set_store(None)


@stored(static_argnames=("power",))
def _moment(x, scale, power):
    return jnp.sum((scale * x) ** power)


@stored
def _radius_sum(planet, x):
    return jnp.sum(planet.radius * x)


class _MyPlanet(jp.Planet):
    """A user's subclass: its code is not in the key."""


def _frames():
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.6, 0.6, (64, 3))
    return x, 0.4 * x[:, ::-1], np.full((64, 3), 0.07)


def test_same_numbers_as_jit_and_written_once(store):
    """A stored kernel (the union integral) gives jax.jit's numbers bit for
    bit; its program is written once and reused from memory."""
    star = jp.Star.quadratic(0.4, 0.26)  # (its profile check is a stored program of its own)
    x, y, r = (jnp.asarray(v) for v in _frames())
    plain = jax.jit(exact_frames.__wrapped__, static_argnames=("order",))(star, x, y, r, order=20)
    before, files = dict(counts), len(list(store.glob("*.exe")))
    first = exact_frames(star, x, y, r, 20)
    again = exact_frames(star, x, y, r, order=20)
    np.testing.assert_array_equal(np.asarray(first), np.asarray(plain))
    np.testing.assert_array_equal(np.asarray(again), np.asarray(plain))
    assert counts["compiled"] - before["compiled"] == 1
    assert len(list(store.glob("*.exe"))) == files + 1


def test_key_follows_static_arguments_shapes_and_static_fields(store):
    """Another static argument, shape, dtype or static field of a Module is
    another program; the same call is the same program."""
    x = jnp.arange(4.0)
    assert float(_moment(x, 1.0, power=2)) == 14.0
    assert float(_moment(x, 1.0, power=3)) == 36.0
    assert float(_moment(jnp.arange(5.0), 1.0, power=2)) == 30.0
    assert float(_moment(jnp.arange(4, dtype=jnp.int32), 1.0, power=2)) == 14.0
    assert float(_moment(x, 2.0, power=2)) == 56.0  # another value: the same program
    assert len(list(store.glob("*.exe"))) == 4
    b, c = (jp.Planet(period=3.0, t0=0.0, a=8.0, inc=89.0, radius=0.5, name=n) for n in "bc")
    assert float(_radius_sum(b, jnp.arange(3.0))) == float(_radius_sum(c, jnp.arange(3.0))) == 1.5
    assert len(list(store.glob("*.exe"))) == 6  # the planet's name (a static field) is in the key


def test_what_the_key_cannot_cover_is_not_stored(store, monkeypatch):
    """A user's subclass (its code is not in the key) and a package edited
    after import (its files no longer the code that runs) take the jitted
    path: the right numbers, nothing written; the edit turns the store off."""
    mine = _MyPlanet(period=3.0, t0=0.0, a=8.0, inc=89.0, radius=0.5, name="b")
    assert float(_radius_sum(mine, jnp.arange(3.0))) == 1.5
    assert not list(store.glob("*.exe"))
    monkeypatch.setitem(_programs._PACKAGE, "stamp", ())
    assert float(_moment(jnp.arange(6.0), 1.0, power=2)) == 55.0
    assert not list(store.glob("*.exe"))
    assert _programs.store_folder() is None


def test_traced_calls_and_transformations_bypass_the_store(store):
    """Under jit, grad and vmap a stored function is the jitted one (nothing
    is written), with the same numbers."""
    x = jnp.arange(3.0)
    g = jax.grad(lambda s: _moment(x, s, power=2))(2.0)
    assert float(g) == pytest.approx(2 * 2.0 * 5.0)
    v = jax.vmap(lambda s: _moment(x, s, power=2))(jnp.array([1.0, 2.0]))
    np.testing.assert_allclose(np.asarray(v), [5.0, 20.0])
    assert float(jax.jit(lambda s: _moment(x, s, power=2))(1.0)) == 5.0
    assert not list(store.glob("*.exe"))


def test_damaged_file_is_compiled_again(store):
    """A damaged program file is not trusted: the program is compiled again
    and the right number returned."""
    x = jnp.arange(4.0)
    _programs._Stored(_moment.__wrapped__, ("power",))(x, 1.0, power=2)  # no program in memory: written
    (path,) = store.glob("*.exe")
    path.write_bytes(b"not a program")
    fresh = _programs._Stored(_moment.__wrapped__, ("power",))
    before = counts["compiled"]
    assert float(fresh(x, 1.0, power=2)) == 14.0
    assert counts["compiled"] == before + 1


def test_closures_and_callbacks_are_refused():
    """A function with closure cells cannot be stored (what it closes over is
    not in the key); a program with a host callback is never written."""
    offset = 1.0

    def shifted(x):
        return x + offset

    with pytest.raises(ValueError, match="closure cells"):
        stored(shifted)
    text = jax.jit(lambda x: jax.pure_callback(np.sin, jax.ShapeDtypeStruct((), jnp.float64), x)).lower(1.0).as_text()
    assert any("callback" in t for t in custom_call_targets(text))


@stored
def _printed(x):
    jax.debug.callback(lambda v: None, x)
    return 2.0 * x


def test_program_with_callback_not_written(store):
    assert float(_printed(jnp.float64(1.5))) == 3.0
    assert not list(store.glob("*.exe"))


def test_package_hash_follows_the_source(tmp_path):
    """An edited source file changes every key (the package hash)."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "kernel.py").write_text("SCALE = 1.0\n")
    (pkg / "table.dat").write_text("1 2 3\n")
    h0 = _programs._package_hash(pkg)
    assert _programs._package_hash(pkg) == h0
    (pkg / "kernel.py").write_text("SCALE = 2.0\n")
    h1 = _programs._package_hash(pkg)
    assert h1 != h0
    (pkg / "table.dat").write_text("1 2 4 5\n")
    assert _programs._package_hash(pkg) != h1


NEW_PROCESS = textwrap.dedent("""
    import sys
    import jax, jax.numpy as jnp, numpy as np
    jax.config.update("jax_enable_x64", True)
    import jaxppo as jp
    from jaxppo.model._programs import counts, stored
    from jaxppo.activity._ppo_or_spot import _solve_bump
    from jaxppo.model._terms import exact_frames
    star = jp.Star.quadratic(0.4, 0.26)  # before the store: its profile check is not counted
    jp.compilation_cache(sys.argv[1])
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.6, 0.6, (64, 3))
    f = exact_frames(star, jnp.asarray(x), jnp.asarray(0.4 * x[:, ::-1]),
                     jnp.asarray(np.full((64, 3), 0.07)), 20)
    t = jnp.linspace(-0.1, 0.1, 50)
    y = 1.0 + 5e-4 * jnp.exp(-0.5 * (t / 0.02) ** 2)
    th, chi2, ok = _solve_bump(1, jnp.zeros(3), t, y, jnp.full(50, 1e-5), jnp.ones(50),
                               jnp.array([1e-3, -0.05, 0.05, 0.005, 0.05]))
    print(repr(float(np.sum(f))), repr(float(chi2)), counts["loaded"], counts["compiled"])
""")


def test_new_process_loads_what_the_first_compiled(tmp_path):
    """A second process loads the programs (the union integral and the
    bump's Levenberg-Marquardt solve, whose QR calls LAPACK) instead of
    compiling them, and gets the first's numbers exactly. (Without loading
    LAPACK first, the loaded solve crashed the process.)"""
    script = tmp_path / "run.py"
    script.write_text(NEW_PROCESS)
    env = dict(os.environ, JAXPPO_CACHE="1")
    runs = [subprocess.run([sys.executable, str(script), str(tmp_path / "cache")], env=env, capture_output=True,
                           text=True, timeout=300) for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr[-2000:]
    first, second = (run.stdout.split() for run in runs)
    assert first[:2] == second[:2]
    assert (first[2], first[3]) == ("0", "2")
    assert (second[2], second[3]) == ("2", "0")
    assert len(list((tmp_path / "cache" / "programs").glob("*.exe"))) == 2


def test_scan_outputs_identical_with_the_store_cold_and_warm(tmp_path):
    """`jaxppo scan` (the bundled real Kepler-20 data, its dips fitted by the
    PPO-or-spot alternatives) without the store, with it empty (programs
    compiled and written) and with it full (programs loaded): the same
    tables, summary and figures, byte for byte."""
    jaxppo = os.path.join(os.path.dirname(sys.executable), "jaxppo")
    runs = {"off": "0", "cold": "1", "warm": "1"}
    for name, on in runs.items():
        env = dict(os.environ, JAXPPO_CACHE=on, JAXPPO_CACHE_DIR=str(tmp_path / "cache"))
        run = subprocess.run([jaxppo, "scan", "--quiet", "--alpha", "0", "360", "10", "--out", str(tmp_path / name)],
                             env=env, capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-2000:]
    assert len(list((tmp_path / "cache" / "programs").glob("*.exe"))) >= 5
    names = sorted(p.name for p in (tmp_path / "off").iterdir() if p.suffix in (".csv", ".md", ".png"))
    assert "scan.csv" in names and "ppo_or_spot.png" in names and len(names) >= 9
    for name in ("cold", "warm"):
        for f in names:
            assert (tmp_path / name / f).read_bytes() == (tmp_path / "off" / f).read_bytes(), (name, f)
        summary = json.loads((tmp_path / name / "summary.json").read_text())
        off = json.loads((tmp_path / "off" / "summary.json").read_text())
        for s, d in ((summary, name), (off, "off")):
            s.pop("seconds")
            s.update(json.loads(json.dumps(s).replace(str(tmp_path / d), "OUT")))
        assert summary == off, name


def test_fit_identical_with_the_store_cold_and_warm(tmp_path):
    """`jaxppo fit` (the bundled synthetic Kepler-20 set, b.t0 and c.radius
    free: its residuals, Jacobian and Levenberg-Marquardt passes are stored
    programs) without the store, with it empty and with it full: the same
    values, errors and chi^2, digit for digit."""
    jaxppo = os.path.join(os.path.dirname(sys.executable), "jaxppo")
    out = {}
    for name, on in {"off": "0", "cold": "1", "warm": "1"}.items():
        env = dict(os.environ, JAXPPO_CACHE=on, JAXPPO_CACHE_DIR=str(tmp_path / "cache"))
        run = subprocess.run([jaxppo, "fit", "--quiet", "--free", "b.t0", "c.radius"], env=env, capture_output=True,
                             text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-2000:]
        out[name] = [line for line in run.stdout.splitlines() if not line.endswith(" s")]
    assert len(list((tmp_path / "cache" / "programs").glob("*.exe"))) >= 3
    assert any(line.startswith("chi2 = ") for line in out["off"]) and len(out["off"]) >= 3
    assert out["cold"] == out["off"] and out["warm"] == out["off"]


LIBRARY = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[2])
    import jax, jax.numpy as jnp
    jax.config.update("jax_enable_x64", True)
    import jaxppo as jp
    from jaxppo.model._programs import counts, stored
    import jnkepler  # a stand-in first on sys.path: a library whose code a stored program traces
    jp.compilation_cache(sys.argv[1])

    @stored
    def through_library(x):
        return jnkepler.scale(x)

    print(repr(float(through_library(jnp.arange(4.0)))), counts["loaded"], counts["compiled"])
""")


def test_a_traced_library_edited_or_replaced_is_compiled_again(tmp_path):
    """Issue 26 review: a stored program that traces another library's code
    (jaxppo's N-body programs trace jnkepler's integrator) is not loaded
    where that library changed: edited in place, or another copy first on
    sys.path (here a stand-in named jnkepler). Before, the key held no
    version of jnkepler, and a process
    with an edited jnkepler got the old program's chi^2 (45024.2 where its
    own code gave 45012.4)."""
    script = tmp_path / "run.py"
    script.write_text(LIBRARY)
    lib = tmp_path / "lib"
    (lib / "jnkepler").mkdir(parents=True)
    source = lib / "jnkepler" / "__init__.py"
    other = tmp_path / "other"
    (other / "jnkepler").mkdir(parents=True)
    (other / "jnkepler" / "__init__.py").write_text("def scale(x):\n    return 5.0 * x.sum()\n")
    env = dict(os.environ, JAXPPO_CACHE="1")

    def run(path):
        out = subprocess.run([sys.executable, str(script), str(tmp_path / "cache"), str(path)], env=env,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr[-2000:]
        value, loaded, compiled = out.stdout.split()
        return float(value), int(loaded), int(compiled)

    source.write_text("def scale(x):\n    return 2.0 * x.sum()\n")
    assert run(lib) == (12.0, 0, 1)
    assert run(lib) == (12.0, 1, 0)  # the same library: loaded
    source.write_text("def scale(x):\n    return 3.0 * x.sum()\n")  # edited in place
    os.utime(source, ns=(source.stat().st_atime_ns, source.stat().st_mtime_ns + 10**9))
    assert run(lib) == (18.0, 0, 1)
    assert run(other) == (30.0, 0, 1)  # another copy first on sys.path
    assert run(lib) == (18.0, 1, 0)


def test_library_stamp_follows_version_place_and_files(tmp_path, monkeypatch):
    """``library_stamp``: none where the library is not installed; a
    different stamp for another copy or an edited file."""
    assert _programs.library_stamp("no_such_library_here") == "no_such_library_here=none"
    assert _programs.library_stamp("equinox").startswith("equinox=")
    for name in ("a", "b"):
        (tmp_path / name / "stamplib").mkdir(parents=True)
        (tmp_path / name / "stamplib" / "__init__.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path / "a"))
    first = _programs.library_stamp("stamplib")
    assert _programs.library_stamp("stamplib") == first
    (tmp_path / "a" / "stamplib" / "__init__.py").write_text("X = 22\n")
    edited = _programs.library_stamp("stamplib")
    assert edited != first
    monkeypatch.syspath_prepend(str(tmp_path / "b"))
    import importlib
    importlib.invalidate_caches()
    assert _programs.library_stamp("stamplib") not in (first, edited)


SAME_CODE = textwrap.dedent("""
    import sys
    import jax, numpy as np
    jax.config.update("jax_enable_x64", True)
    import jaxppo as jp
    from jaxppo.model._programs import counts
    from jaxppo.activity._ppo_or_spot import _own_depth
    star = jp.Star.quadratic(0.4, 0.26)  # before the store: its profile check is not counted
    jp.compilation_cache(sys.argv[1])
    for name in sys.argv[2]:
        planet = jp.Planet(period=3.0, t0=0.0, a=8.0, inc=89.0, radius=0.08, name=name)
        print(repr(float(_own_depth(star, planet, np.array([0.001])))), counts["loaded"], counts["failed"])
""")


def test_programs_of_the_same_code_load_alone(tmp_path):
    """Two stored programs of the same XLA code (planets b and c: their
    names are static, the program is the same) compiled in one process; a
    new process loads c's alone and gets the same depth. (c's executable
    came from JAX's persistent cache and was serialized without its
    kernels: "Function multiply_cosine_fusion not found".)"""
    script = tmp_path / "run.py"
    script.write_text(SAME_CODE)
    env = dict(os.environ, JAXPPO_CACHE="1")
    first, second = (subprocess.run([sys.executable, str(script), str(tmp_path / "cache"), names], env=env,
                                    capture_output=True, text=True, timeout=300) for names in ("bc", "c"))
    assert first.returncode == 0, first.stderr[-2000:]
    assert second.returncode == 0, second.stderr[-2000:]
    depth_b, depth_c = (line.split()[0] for line in first.stdout.splitlines())
    assert depth_b == depth_c
    assert second.stdout.split() == [depth_c, "1", "0"]


def _programs_load_but_do_not_run(monkeypatch):
    """Every program read from the store from now on fails when it runs (as
    one whose serialization lacked its kernels)."""

    def broken(*args, **kwargs):
        def run(*inputs):
            raise jax.errors.JaxRuntimeError("NOT_FOUND: Function fusion not found")
        return run

    from jax.experimental import serialize_executable

    monkeypatch.setattr(serialize_executable, "deserialize_and_load", broken)


def test_a_stored_program_that_does_not_run_is_removed(store, monkeypatch):
    """A program read from the store that fails when it runs is removed and
    the call answered by the jitted path."""
    x = jnp.arange(4.0)
    _programs._Stored(_moment.__wrapped__, ("power",))(x, 1.0, power=2)
    (path,) = store.glob("*.exe")
    _programs_load_but_do_not_run(monkeypatch)
    before = counts["failed"]
    assert float(_programs._Stored(_moment.__wrapped__, ("power",))(x, 1.0, power=2)) == 14.0
    assert counts["failed"] == before + 1
    assert not path.exists()


def test_key_follows_every_jax_option_and_xla_flags(store, monkeypatch):
    """JAX's options (every one: explicit x64 dtypes, matmul precision, ...)
    and XLA's flags are in the key: a program traced under other options is
    another program (a fast-math program loaded without the flags answered
    NaN where jit gave -1)."""
    names = dict(_programs._options())
    assert "jax_explicit_x64_dtypes" in names and "jax_default_matmul_precision" in names
    x = jnp.arange(4.0)
    moment = _programs._Stored(_moment.__wrapped__, ("power",))  # nothing in memory
    moment(x, 1.0, power=2)
    with jax.default_matmul_precision("float32"):
        moment(x, 1.0, power=2)
    assert len(list(store.glob("*.exe"))) == 2
    base = _programs._environment(_programs._stable(_programs._options()))
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_enable_fast_math=true")
    _programs._environment.cache_clear()
    assert _programs._environment(_programs._stable(_programs._options())) != base
    _programs._environment.cache_clear()


def test_nan_checks_lambdas_and_constants(store, monkeypatch):
    """Under jax_debug_nans a call takes jit's path (which names the failing
    operation); lambdas and nested functions cannot be stored (two of them
    share a name); a module-level value of jaxppo set anew (a kernel reads
    it while traced) turns the store off, as an edited file does."""
    with pytest.raises(ValueError, match="not a module-level function"):
        stored(lambda x: x + 1.0)
    with jax.debug_nans(True):
        assert float(_moment(jnp.arange(3.0), 1.0, power=2)) == 5.0
    assert not list(store.glob("*.exe"))
    from jaxppo.model import _plan

    monkeypatch.setattr(_plan, "INNER_MARGIN", 50.0)
    assert float(_moment(jnp.arange(7.0), 1.0, power=2)) == 91.0
    assert not list(store.glob("*.exe")) and _programs.store_folder() is None


def test_damaged_payload_is_never_loaded(store):
    """A file whose bytes changed (one flipped byte inside a readable
    pickle killed the loading process with SIGILL) fails its checksum: the
    program is compiled again, never handed to the loader."""
    x = jnp.arange(4.0)
    _programs._Stored(_moment.__wrapped__, ("power",))(x, 1.0, power=2)
    (path,) = store.glob("*.exe")
    blob = bytearray(path.read_bytes())
    blob[len(blob) // 2] ^= 0x01
    path.write_bytes(bytes(blob))
    before = dict(counts)
    assert float(_programs._Stored(_moment.__wrapped__, ("power",))(x, 1.0, power=2)) == 14.0
    assert counts["loaded"] == before["loaded"] and counts["compiled"] == before["compiled"] + 1


def test_precompile_compiles_in_a_thread_and_the_call_takes_that_program(store):
    """``precompile`` compiles the program of a call's shapes beside the
    caller (in a thread of its own): the call with those shapes runs that
    program (one compilation in all, jit's numbers, one file); a call of
    other shapes compiles its own; a program already loaded is not
    compiled again, one in the store is read in the thread (and run by the
    call); with the store off nothing happens."""
    moment = _programs._Stored(_moment.__wrapped__, ("power",))
    x = jnp.linspace(0.0, 1.0, 7)
    before = counts["compiled"]
    moment.precompile(x, 2.0, power=3)
    assert len(moment._pending) == 1
    out = moment(x, 2.0, power=3)
    assert counts["compiled"] - before == 1 and not moment._pending
    assert float(out) == float(jax.jit(_moment.__wrapped__, static_argnames=("power",))(x, 2.0, power=3))
    assert len(list(store.glob("*.exe"))) == 1
    moment.precompile(x, 5.0, power=3)  # loaded in memory: the same program
    fresh = _programs._Stored(_moment.__wrapped__, ("power",))
    loaded = counts["loaded"]
    fresh.precompile(x, 2.0, power=3)  # in the store: read in the thread, run by the call
    assert not moment._pending and list(fresh._pending.values())[0][1] is True
    assert float(fresh(x, 2.0, power=3)) == float(out)
    assert not fresh._pending and counts["compiled"] - before == 1 and counts["loaded"] == loaded + 1
    moment.precompile(x, 2.0, power=2)  # another static value: another program
    assert float(moment(x, 2.0, power=2)) == pytest.approx(float(jnp.sum((2.0 * x) ** 2)), rel=1e-15)
    assert counts["compiled"] - before == 2
    set_store(None)
    moment.precompile(x[:3], 2.0, power=3)
    assert not moment._pending


def test_a_program_precompile_read_that_does_not_run_is_removed(store, monkeypatch):
    """A program ``precompile`` read from the store runs once in the call
    before it is trusted, as one the call reads itself: where it fails,
    it is removed and the call answered by the jitted path."""
    x = jnp.arange(4.0)
    _programs._Stored(_moment.__wrapped__, ("power",))(x, 1.0, power=2)
    (path,) = store.glob("*.exe")
    _programs_load_but_do_not_run(monkeypatch)
    moment = _programs._Stored(_moment.__wrapped__, ("power",))
    moment.precompile(x, 1.0, power=2)
    before = counts["failed"]
    assert float(moment(x, 1.0, power=2)) == 14.0
    assert counts["failed"] == before + 1 and not path.exists() and not moment._pending


def test_a_precompile_that_fails_leaves_the_call_to_compile(store, monkeypatch):
    """An error in ``precompile``'s thread costs only time: the call
    compiles the program itself and answers as jit does."""
    moment = _programs._Stored(_moment.__wrapped__, ("power",))
    real = _programs._Stored._finish
    calls = []

    def failing_once(self, *args):
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError("compiler crashed")
        return real(self, *args)

    monkeypatch.setattr(_programs._Stored, "_finish", failing_once)
    x = jnp.arange(4.0)
    moment.precompile(x, 1.0, power=2)
    assert float(moment(x, 1.0, power=2)) == 14.0
    assert len(calls) == 2 and not moment._pending


FRESH_INSTALL = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[2])
    import jax, numpy as np
    jax.config.update("jax_enable_x64", True)
    import jaxppo as jp
    from jaxppo.model._programs import counts, store_folder
    assert jp.__file__.startswith(sys.argv[2]), jp.__file__
    jp.compilation_cache(sys.argv[1])
    flux = jp.kepler20_system().flux(np.linspace(334.0, 335.0, 100))
    print(repr(float(np.sum(flux))), counts["loaded"], counts["compiled"], store_folder() is not None)
""")


def test_a_new_install_second_run_loads_the_first_runs_programs(tmp_path):
    """A package without bytecode (a new install): its first run writes the
    .pyc files as it imports, which neither turns the store off nor changes
    the key; the second run loads every program the first compiled. (The
    first run's store turned itself off, and the second, whose key held the
    new bytecode, compiled everything again.)"""
    import shutil

    copy = tmp_path / "site"
    shutil.copytree(os.path.dirname(jp.__file__), copy / "jaxppo", ignore=shutil.ignore_patterns("__pycache__"))
    script = tmp_path / "run.py"
    script.write_text(FRESH_INSTALL)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["JAXPPO_CACHE"] = "1"
    runs = [subprocess.run([sys.executable, str(script), str(tmp_path / "cache"), str(copy)], env=env,
                           capture_output=True, text=True, timeout=300) for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr[-2000:]
    first, second = (run.stdout.split() for run in runs)
    assert list((copy / "jaxppo").rglob("*.pyc"))  # the first run wrote its bytecode
    assert first[3] == "True" and int(first[2]) >= 2 and first[1] == "0", first
    assert second[0] == first[0] and second[1:] == [first[2], "0", "True"], (first, second)


def test_stale_bytecode_counts_only_where_python_runs_it(tmp_path):
    """A .pyc written after its source changed is the source's own code (no
    part of the key); one whose header matches a source edited later within
    the same second, keeping its size, is what Python runs: it enters the
    key."""
    import importlib.util
    import py_compile

    src = tmp_path / "kernel.py"
    src.write_text("SCALE = 1.0\n")
    assert _programs._stale_bytecode(src) is None  # no bytecode
    py_compile.compile(str(src))
    assert _programs._stale_bytecode(src) is None  # written after the source
    pyc = Path(importlib.util.cache_from_source(str(src)))
    st = src.stat()
    src.write_text("SCALE = 2.0\n")  # same size
    os.utime(src, ns=(st.st_atime_ns, st.st_mtime_ns))  # the same second as the bytecode's header
    os.utime(pyc, ns=(st.st_mtime_ns - 1, st.st_mtime_ns - 1))  # written before that edit
    assert _programs._stale_bytecode(src) == pyc.read_bytes()
    h = _programs._package_hash(tmp_path)
    pyc.unlink()
    assert _programs._package_hash(tmp_path) != h


def test_map_to_host_runs_the_callers_programs_in_threads(store, monkeypatch):
    """``map_to_host`` gives each call's outputs as the call itself does
    (bit for bit, as numpy arrays), the calls spread over the threads; the
    program is chosen in the caller's thread, whose JAX options may be its
    own (under ``jax.enable_x64(False)`` the threads would otherwise run
    the float64 program); an argument that is not the first call's object
    or an array of its shape is planned afresh; with the store off every
    call runs in the caller's thread."""
    moment = _programs._Stored(_moment.__wrapped__, ("power",))
    xs = [jnp.linspace(0.0, 1.0 + i, 7) for i in range(5)]
    scale = 2.0
    used = []
    real_map = concurrent.futures.ThreadPoolExecutor.map

    def spy(pool, fn, jobs):
        jobs = list(jobs)
        used.append((pool._thread_name_prefix, len(jobs)))
        return real_map(pool, fn, jobs)

    # (jaxppo's own names are left alone: setting one turns the store off)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    monkeypatch.setattr(concurrent.futures.ThreadPoolExecutor, "map", spy)
    assert _programs.threads() == 2
    calls = [(x, scale, 3) for x in xs]
    out = moment.map_to_host(calls)
    assert used == [("jaxppo-program", 4)]  # the first call loaded the program here
    for got, args in zip(out, calls):
        assert isinstance(got, np.ndarray) and got.dtype == np.float64
        np.testing.assert_array_equal(got, np.asarray(moment(*args)))
    with jax.enable_x64(False):
        calls32 = [(jnp.linspace(0.0, 1.0 + i, 7), scale, 3) for i in range(3)]
        out32 = moment.map_to_host(calls32)
        want32 = [np.asarray(moment(*args)) for args in calls32]
    assert used[1:] == [("jaxppo-program", 2)]
    assert all(got.dtype == np.float32 for got in out32)
    for got, want in zip(out32, want32):
        np.testing.assert_array_equal(got, want)
    # another static value in one call: planned on its own, its own program
    mixed = moment.map_to_host([(xs[0], scale, 3), (xs[1], scale, 2)])
    assert float(mixed[1]) == pytest.approx(float(jnp.sum((scale * xs[1]) ** 2)), rel=1e-15)
    set_store(None)
    used.clear()
    plain = moment.map_to_host(calls)
    assert used == []
    for got, want in zip(plain, out):
        np.testing.assert_array_equal(got, want)
