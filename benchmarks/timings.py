"""The one table of end-to-end timings that README.md and docs/ quote:
each command run as a user runs it (a fresh process, wall clock, compile
included), on this machine, in one run. Writes docs/timings.md.

    python benchmarks/timings.py [--out docs/timings.md]

Rows:
* `jaxppo scan` (the README's main job, bundled real Kepler-20 data): first
  run with an empty JAX compilation cache, and a second run (warm cache);
* `jaxppo ttv` on the bundled real Kepler-51 data (51 transit times);
* `jaxppo fit` of the synthetic Kepler-20 example (default free set),
  first and second run;
* `jp.fit` of Kepler-20 b + c, 10 free parameters, ~2,900 points: a new
  Python process with ``jp.compilation_cache()``, first and second run
  (benchmarks/fit_timing.py --once);
* the stages of a warm `jaxppo scan` (import, config and data, the scan,
  the figures and the PPO-or-spot fits side by side);
* `jp.fit` cold and warm in one process (benchmarks/fit_timing.py --no-nuts).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def _run(cmd: list[str], env: dict) -> tuple[float, str]:
    t = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
    dt = time.perf_counter() - t
    # 1: also `jaxppo fit` / `ttv` whose fit did not converge (timed); a crash is not a timing
    crashed = "Traceback (most recent call last)" in proc.stderr or ": internal error:" in proc.stderr
    if proc.returncode not in (0, 1) or crashed:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return dt, proc.stdout + proc.stderr


STAGES = r"""
import sys, time
t = [time.perf_counter()]
import jaxppo.cli as cli
from jaxppo.obliquity._config import load_config
from jaxppo.obliquity._scan import run_scan, scan_products
from jaxppo.obliquity._worker import Drawer
cli._enable_x64()
t.append(time.perf_counter())
with Drawer(cli._enable_x64) as drawer:
    cfg = load_config(None)
    t.append(time.perf_counter())
    result = run_scan(cfg, sys.argv[1], restart=True, progress=False)
    t.append(time.perf_counter())
    wait = drawer.run(sum, [0])  # what is left to the drawing process when the scan ends
    wait()
    t.append(time.perf_counter())
    scan_products(result, cfg, sys.argv[1], drawer)
    t.append(time.perf_counter())
print(" ".join(f"{b - a:.2f}" for a, b in zip(t, t[1:])))
"""


def _stages(env: dict) -> list:
    """Where the seconds of a warm `jaxppo scan` go: the stages timed in a
    new process (the cache warm from the rows before)."""
    with tempfile.TemporaryDirectory(prefix="jaxppo_stages_") as out:
        _, text = _run([sys.executable, "-c", STAGES, out], env)
    try:
        imp, load, scan, ready, products = (float(v) for v in text.strip().splitlines()[-1].split())
    except ValueError:
        return [("`jaxppo scan` stages", float("nan"), "could not be timed")]
    return [("stages of a later default scan: importing jaxppo and its CLI", imp, ""),
            ("... loading the config and the real Kepler-20 light curve", load, ""),
            ("... the scan itself (chi^2 over the alpha grid, tables)", scan, ""),
            ("... waiting for the drawing process to be ready", ready, "its start overlaps the above"),
            ("... Figs. 4 and 6 (drawing process) beside the PPO-or-spot fits and the other figures (this one)", products, "")]


CALIBRATION = """
import time
t = time.perf_counter()
s = 0
for i in range(5_000_000):
    s += i * i
print(time.perf_counter() - t)
"""


def _calibration(env: dict) -> float:
    """Seconds of a fixed pure-Python loop (5e6 multiply-adds) in a new
    process, the least of three: how fast this machine is while the table is
    measured (a shared 2-core machine: the same code took 10.8 and 13.6 s
    for the first scan an hour apart)."""
    return min(float(_run([sys.executable, "-c", CALIBRATION], env)[1].split()[-1]) for _ in range(3))


def _versions() -> str:
    """The versions of the libraries whose import and compilation the
    timings include (ml_dtypes 0.7.0 alone added 0.6 s to every import of
    jax: pyproject.toml caps it)."""
    from importlib import metadata

    out = []
    for name in ("jax", "jaxlib", "numpy", "ml_dtypes", "equinox", "numpyro", "matplotlib"):
        try:
            out.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            out.append(f"{name} none")
    return ", ".join(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(ROOT / "docs" / "timings.md"))
    args = ap.parse_args()
    jaxppo = str(Path(sys.executable).with_name("jaxppo"))
    rows = []
    with tempfile.TemporaryDirectory(prefix="jaxppo_timings_") as tmp:
        # Python writes its bytecode as on a user's machine (a sandbox that
        # sets PYTHONDONTWRITEBYTECODE compiles every source at every import)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env.update(JAXPPO_CACHE_DIR=str(Path(tmp) / "cache"), JAXPPO_CACHE="1")
        for label in ("first run (empty compilation cache)", "second run (warm cache)"):
            dt, out = _run([jaxppo, "scan", "--out", str(Path(tmp) / "scan"), "--restart", "--quiet"], env)
            rows.append((f"`jaxppo scan` (README main job, real Kepler-20 LC), {label}", dt, ""))
        cfg = ROOT / "jaxppo" / "data" / "kepler51" / "kepler51_llc.toml"
        dt, out = _run([jaxppo, "ttv", str(cfg), "--out", str(Path(tmp) / "ttv"), "--quiet"], env)
        first = out.strip().splitlines()[0] if out.strip() else ""
        rows.append(("`jaxppo ttv` (real Kepler-51 LC, 51 transit times)", dt, first.split(",")[0]))
        for label in ("first run", "second run (warm cache)"):
            dt, out = _run([jaxppo, "fit", "--quiet"], env)
            rows.append((f"`jaxppo fit` (synthetic Kepler-20 example, default free set), {label}", dt, ""))
        for label in ("first run (empty compilation cache)", "second run (the programs the first compiled)"):
            dt, out = _run([sys.executable, str(HERE / "fit_timing.py"), "--once", "--cache", str(Path(tmp) / "fitcache")],
                           env)
            call = re.search(r"fit: ([0-9.]+) s", out)
            rows.append((f"`jp.fit` Kepler-20 b + c, a new Python process with `jp.compilation_cache()`, {label}", dt,
                         f"the fit call itself {float(call.group(1)):.1f} s" if call else "benchmarks/fit_timing.py --once"))
        rows += _stages(env)
        speed = _calibration(env)
        t = time.perf_counter()
        proc = subprocess.run([sys.executable, str(HERE / "fit_timing.py"), "--no-nuts"], capture_output=True, text=True,
                              cwd=ROOT, env=env)
        dt = time.perf_counter() - t
        cold = re.search(r"fit: ([0-9.]+) s cold", proc.stdout)
        warm = re.search(r"([0-9.]+) s second call", proc.stdout)
        rows.append(("`jp.fit` Kepler-20 b + c, 10 free, ~2,900 points: cold (compile included)",
                     float(cold.group(1)) if cold else float("nan"), "benchmarks/fit_timing.py --no-nuts"))
        rows.append(("`jp.fit` the same problem again in the same process (warm)",
                     float(warm.group(1)) if warm else float("nan"), ""))
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    load = os.getloadavg()
    lines = ["# Timings", "",
             "Generated by `python benchmarks/timings.py` (do not edit by hand): every command in a fresh",
             "process as a user runs it, wall clock, compilation included, in one run on this machine.",
             "README.md and the other docs quote these numbers. Python writes its bytecode as usual",
             "(`PYTHONDONTWRITEBYTECODE` is dropped from the commands' environment).", "",
             f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
             f"{platform.python_version()}; {now}; load average at the end {load[0]:.2f}.", "",
             f"Versions: {_versions()}.", "",
             f"Machine speed while measured: a fixed pure-Python loop (5e6 multiply-adds, benchmarks/timings.py "
             f"CALIBRATION) took {speed:.2f} s, the least of three (compare it across tables: this shared machine's "
             "speed changes by more than the +-30 % below within an hour).", "",
             "| what | seconds | note |", "|---|---:|---|"]
    lines += [f"| {w} | {s:.1f} | {n} |" for w, s, n in rows]
    lines += ["", "Timings on this 2-core machine vary by about +-30 % from run to run."]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
