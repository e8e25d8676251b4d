"""One run of the throughput benchmarks on an accelerator (H100 / H200), with
a small --quick mode for a smoke test on a CPU.

    python benchmarks/gpu.py --out gpu_out            # on the GPU machine
    python benchmarks/gpu.py --quick --out /tmp/gpu   # smoke test on a CPU

Parts (--parts picks some; all by default):

grid   the paper's Kepler-20 b + c obliquity grid (benchmarks/kepler20_grid.py:
       2 cases x 360 alphas x the seven double transits at 1-minute cadence),
       float64, jp.sweep;
sweep  about 1e7 frames (--quick: 1e5) of jp.sweep on the same system, the
       alpha grid made finer and the transit windows repeated, in float64
       and in float32, with the largest |float32 - float64|;
nuts   benchmarks/sample_vs_jaxoplanet.py with one start and one cadence;
joint  benchmarks/joint.py injected (skipped by --quick: its mode search
       has no size option and takes over 10 minutes on a 2-core CPU);
chart  benchmarks/speed_accuracy.py, its chart written under OUT.

Every measurement runs in a fresh process (this script with --child, or the
benchmark script), so "cold" is the first call with compilation (JAX's
persistent compilation cache off) and "warm" the best of --repeats further
calls. Each process reports the device it ran on; a figure from another
device than the one named in the header is labelled with its own device.
Writes OUT/gpu.json (every number, the devices, the JAX version, the
float64 flags), OUT/gpu.md (the tables) and OUT/logs/*.log (full output).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PARTS = ("grid", "sweep", "nuts", "joint", "chart")
MARK = "@@gpu.py "  # prefix of the JSON lines a child process prints
# Runs a benchmark script after printing the device it will run on.
WRAP = ("import json, runpy, sys, jax; d = jax.devices(); "
        "print(%r + json.dumps(dict(device_kind=d[0].device_kind, platform=d[0].platform, count=len(d))), flush=True); "
        "sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')") % MARK


def load_grid_module():
    """Import benchmarks/kepler20_grid.py (it enables float64 on import)."""
    spec = importlib.util.spec_from_file_location("kepler20_grid", HERE / "kepler20_grid.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def device_info() -> dict:
    """The first device's kind and platform, the device count and versions."""
    import jax

    d = jax.devices()
    return dict(device_kind=d[0].device_kind, platform=d[0].platform, count=len(d),
                devices=[str(x) for x in d], jax_version=jax.__version__,
                jax_enable_x64=bool(jax.config.jax_enable_x64))


def timed_calls(run, repeats: int):
    """Wall time of the first call of ``run`` (with compilation) and the best
    of ``repeats`` further calls [s], each call's result brought to the host
    before its timer stops; also the first call's and the last call's result."""
    import numpy as np

    t0 = time.perf_counter()
    first = run()
    np.asarray(first[0])
    cold = time.perf_counter() - t0
    warm = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        last = run()
        np.asarray(last[0])
        warm.append(time.perf_counter() - t0)
    return cold, min(warm), first, last


def child(args) -> None:
    """In a fresh process: time one sweep (grid or scaled) at ``--bits`` and
    print its figures as one JSON line; save the flux with ``--save``."""
    import jax
    import numpy as np

    grid = load_grid_module()  # enables float64 ...
    jax.config.update("jax_enable_x64", args.bits == 64)  # ... set here before any array exists
    import jaxppo as jp
    from jaxppo.model._kepler20 import kepler20_system

    system = kepler20_system()
    t = grid.grid_times(system)
    if args.child == "grid":
        alpha = np.arange(0.0, 360.0, 1.0)
    else:  # about args.frames frames: 2 cases x n_alpha x n_time, the windows repeated
        n_alpha = max(18, int(round(np.sqrt(args.frames / 2.0 / 2.4))))
        alpha = np.linspace(0.0, 360.0, n_alpha, endpoint=False)
        t = np.resize(t, max(1, int(round(args.frames / 2.0 / n_alpha))))
    cold, warm, (_, stats), (flux, _) = timed_calls(lambda: jp.sweep(system, t, alpha, return_stats=True),
                                                    args.repeats)
    if args.save:
        np.save(args.save, np.asarray(flux))
    out = dict(device_info(), what=args.child, bits=args.bits, dtype=str(jax.numpy.zeros(()).dtype),
               cases=2, alphas=int(alpha.size), times=int(t.size), frames=stats.frames, union=stats.union,
               single=stats.single, cold_s=cold, warm_s=warm,
               fps_cold=stats.frames / cold, fps_warm=stats.frames / warm)
    print(MARK + json.dumps(out), flush=True)


def run_process(cmd: list[str], log: Path, timeout: float, shown: str = "") -> dict:
    """Run ``cmd`` from the repository root with the persistent compilation
    cache off; keep its output in ``log``; return its wall time, exit status,
    output lines and the JSON lines it marked (``shown``: the command as
    reported, default ``cmd``)."""
    env = dict(os.environ, JAX_ENABLE_COMPILATION_CACHE="false", JAXPPO_CACHE="0",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
        rc, text = proc.returncode, proc.stdout + proc.stderr
    except subprocess.TimeoutExpired as err:
        rc = "timeout"
        text = "".join(x.decode() if isinstance(x, bytes) else (x or "") for x in (err.stdout, err.stderr))
    wall = time.perf_counter() - t0
    log.parent.mkdir(parents=True, exist_ok=True)
    shown = shown or " ".join(cmd)
    log.write_text(shown + "\n\n" + text)
    lines = text.splitlines()
    marked = [json.loads(x[len(MARK):]) for x in lines if x.startswith(MARK)]
    return dict(cmd=shown, rc=rc, wall_s=wall, log=str(log), marked=marked,
                lines=[x for x in lines if not x.startswith(MARK)])


def sweep_part(what: str, bits: int, frames: int, args, save: str = "") -> dict:
    """Run one timed sweep in a child process; its figures, or the error."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", what, "--bits", str(bits),
           "--frames", str(frames), "--repeats", str(args.repeats)] + (["--save", save] if save else [])
    res = run_process(cmd, args.out / "logs" / f"{what}{bits}.log", args.timeout)
    if res["rc"] != 0 or not res["marked"]:
        return dict(error=f"exit status {res['rc']}; see {res['log']}", tail=res["lines"][-15:])
    return res["marked"][-1]


def sweeps(args) -> dict:
    """The ~1e7-frame sweep in float64 and in float32, and the largest
    |float32 - float64| over its frames."""
    import numpy as np

    frames = int(1e5 if args.quick else 1e7)
    with tempfile.TemporaryDirectory() as tmp:
        r64 = sweep_part("sweep", 64, frames, args, os.path.join(tmp, "f64.npy"))
        r32 = sweep_part("sweep", 32, frames, args, os.path.join(tmp, "f32.npy"))
        if "error" not in r64 and "error" not in r32:
            diff = np.abs(np.load(os.path.join(tmp, "f32.npy")) - np.load(os.path.join(tmp, "f64.npy")))
            r32["max_abs_diff_vs_float64"] = float(diff.max())
    return {"float64": r64, "float32": r32}


def script_part(name: str, argv: list[str], keep, args) -> dict:
    """Run a benchmark script through WRAP (which names its device); keep
    the output lines for which ``keep(line)`` is true as its summary."""
    res = run_process([sys.executable, "-c", WRAP, str(HERE / name)] + argv,
                      args.out / "logs" / f"{Path(name).stem}.log", args.timeout,
                      " ".join(["python", f"benchmarks/{name}"] + argv))
    summary = [x for x in res["lines"] if keep(x)] if res["rc"] == 0 else res["lines"][-15:]
    dev = res["marked"][0] if res["marked"] else None
    return dict(cmd=res["cmd"], rc=res["rc"], wall_s=res["wall_s"], log=res["log"], device=dev, summary=summary)


def nuts(args) -> dict:
    """jp.sample against jaxoplanet + numpyro: one start, one cadence."""
    if args.quick:  # about 1-2 min on a 2-core CPU
        argv = ["--warmup", "50", "--samples", "50", "--chains", "1", "--start", "truth", "--cadence", "2",
                "--window", "0.25"]
    else:
        argv = ["--chains", "1,4", "--start", "off", "--t0-off", "3", "--cadence", "1"]
    keep = ("free", "==", "|", "lowest", "  jax")
    return script_part("sample_vs_jaxoplanet.py", argv, lambda x: x.startswith(keep), args)


def joint(args) -> dict:
    """The joint (alpha, transit parameters) sampler on the injected case;
    skipped by --quick (its mode search has no size option)."""
    if args.quick:
        reason = ("skipped by --quick: joint.py's mode search (55-70 starts per case) has no option to shrink it; "
                  "its full run took 207-321 s end to end on a 2-core CPU (docs/marginal.md)")
        print(f"joint: {reason}", flush=True)
        return dict(skipped=reason)
    return script_part("joint.py", ["injected"], lambda x: "joint_scan end to end" in x or x.startswith("  "), args)


def chart(args) -> dict:
    """The speed-accuracy chart of every method, written under OUT."""
    folder = args.out / "speed_accuracy"
    argv = ["--frames", "20" if args.quick else "400", "--out", str(folder)]
    res = script_part("speed_accuracy.py", argv, lambda x: x.startswith(("exact", "auto", "wrote")), args)
    res["chart"] = str(folder / "speed_accuracy.png") if (folder / "speed_accuracy.png").exists() else None
    return res


def label(row: dict, host: dict) -> str:
    """'' where ``row`` ran on the header's device, else a note naming its own."""
    dev = row.get("device") if "device" in row else row
    if not dev or "device_kind" not in dev:
        return " (device not reported)"
    same = (dev["device_kind"], dev["platform"]) == (host["device_kind"], host["platform"])
    return "" if same else f" (ran on {dev['device_kind']}, {dev['platform']}, not the header's device)"


def tables(results: dict, host: dict) -> list[str]:
    """The markdown report: the sweep table, then each script's summary."""
    head = (f"## jaxppo throughput on {host['device_kind']} ({host['platform']}, {host['count']} device(s)), "
            f"JAX {host['jax_version']}{', quick mode' if results['quick'] else ''}")
    md = [head, "", "| benchmark | precision | frames (cases x alphas x times) | cold [s] | warm [s] | "
          "frames/s cold | frames/s warm | max abs diff vs float64 |", "|---|---|---|---|---|---|---|---|"]
    rows = [("Kepler-20 paper grid", results.get("grid"))]
    rows += [(f"sweep {k}", v) for k, v in results.get("sweep", {}).items()]
    for name, r in rows:
        if r is None:
            continue
        if "error" in r:
            md.append(f"| {name} | | failed: {r['error']} | | | | | |")
            continue
        diff = r.get("max_abs_diff_vs_float64")
        md.append(f"| {name}{label(r, host)} | {r['dtype']} | {r['frames']:,} (2 x {r['alphas']} x {r['times']}; "
                  f"{r['union']:,} union) | {r['cold_s']:.3f} | {r['warm_s']:.3f} | {r['fps_cold']:,.0f} | "
                  f"{r['fps_warm']:,.0f} | {'' if diff is None else f'{diff:.1e}'} |")
    for key, title in (("nuts", "NUTS: jaxppo vs jaxoplanet"), ("joint", "joint sampler"),
                       ("chart", "speed-accuracy chart")):
        r = results.get(key)
        if r is None:
            continue
        if "skipped" in r:
            md += ["", f"### {title}", "", r["skipped"]]
            continue
        md += ["", f"### {title}{label(r, host)}", "",
               f"`{r['cmd']}`: exit status {r['rc']}, {r['wall_s']:.1f} s wall; full output {r['log']}"]
        if r.get("chart"):
            md.append(f"chart: {r['chart']} (its axis label's device is fixed text in speed_accuracy.py; "
                      f"it ran on the device named here)")
        md += ["", "```", *r["summary"], "```"]
    return md


def main() -> None:
    """Parse the options; run the parts (or, with --child, one timed sweep)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, a smoke test on a CPU")
    ap.add_argument("--out", type=Path, default=Path("gpu_out"), help="folder for gpu.json, gpu.md, logs")
    ap.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated subset of {','.join(PARTS)}")
    ap.add_argument("--repeats", type=int, default=3, help="warm calls per sweep (the best is kept)")
    ap.add_argument("--timeout", type=float, default=None, help="[s] per process (default 3600, --quick 300)")
    ap.add_argument("--child", choices=("grid", "sweep"), help=argparse.SUPPRESS)
    ap.add_argument("--bits", type=int, choices=(32, 64), default=64, help=argparse.SUPPRESS)
    ap.add_argument("--frames", type=int, default=int(1e7), help=argparse.SUPPRESS)
    ap.add_argument("--save", default="", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args)
    parts = [p for p in args.parts.split(",") if p]
    if set(parts) - set(PARTS):
        raise SystemExit(f"--parts: choose from {','.join(PARTS)}, got {args.parts!r}")
    args.timeout = args.timeout or (300.0 if args.quick else 3600.0)
    args.out.mkdir(parents=True, exist_ok=True)
    preset = os.environ.get("XLA_PYTHON_CLIENT_PREALLOCATE")
    os.environ["XLA_PYTHON_CLIENT_PREALLOCATE"] = "false"  # this process only names the devices
    host = device_info()
    if preset is None:  # the children allocate as JAX does by default
        del os.environ["XLA_PYTHON_CLIENT_PREALLOCATE"]
    else:
        os.environ["XLA_PYTHON_CLIENT_PREALLOCATE"] = preset
    print(f"device: {host['device_kind']} (platform {host['platform']}, {host['count']} device(s)); "
          f"JAX {host['jax_version']}; {'quick' if args.quick else 'full'} mode; output in {args.out}", flush=True)
    results = dict(host=host, quick=args.quick, parts=parts, started=time.strftime("%Y-%m-%d %H:%M:%S"))
    steps = dict(grid=lambda: sweep_part("grid", 64, 0, args), sweep=lambda: sweeps(args),
                 nuts=lambda: nuts(args), joint=lambda: joint(args), chart=lambda: chart(args))
    for part in parts:
        t0 = time.perf_counter()
        results[part] = steps[part]()
        print(f"[{part} done in {time.perf_counter() - t0:.1f} s]", flush=True)
        (args.out / "gpu.json").write_text(json.dumps(results, indent=1))  # kept after every part
    md = tables(results, host)
    (args.out / "gpu.md").write_text("\n".join(md) + "\n")
    print("\n" + "\n".join(md))
    print(f"\nwrote {args.out / 'gpu.json'} and {args.out / 'gpu.md'}")


if __name__ == "__main__":
    main()
