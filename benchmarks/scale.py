"""Time and peak memory of the obliquity grid as each axis grows, and the
largest grid that fits in a memory budget; sharding over forced CPU devices.

    python benchmarks/scale.py axes [--budget-gb 24] [--out POINTS.json] [--figure PNG]  # docs/scale.png + the table of docs/scale.md
    python benchmarks/scale.py devices [--frames 200000]  # 1, 2, 4 forced host devices

axes: the Kepler-20 b + c grid (jp.sweep over [case, alpha, time], the
seven double transits at 1-minute cadence) grown along one axis at a time
from a base point, and the marginalised scan's chi^2 of D posterior draws
(jaxppo.obliquity._marginal.marginal_chi2: D x case x alpha x time frames). Every point
runs in a fresh process, so its peak resident memory (VmHWM) is its own;
times are the best of three further calls (warm: compiled; persistent
cache off) and the first call (cold). Memory per grid element is the slope of a straight line
through peak memory against elements along each axis; the largest grid in
the budget is (budget - intercept) / slope, an extrapolation beyond the
measured sizes (stated as such in the output).

devices: the same concrete "auto" and "exact" batch of overlapping pairs
(and a sweep) with XLA_FLAGS=--xla_force_host_platform_device_count=N,
N = 1, 2, 4: the frames are sharded over the N devices (jaxppo.model._plan._shard).
On a machine with fewer cores than devices the devices share the cores.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = textwrap.dedent(r"""
    import json, sys, time
    import jax
    jax.config.update("jax_enable_x64", True)
    import numpy as np
    import jaxppo as jp
    from jaxppo.model._kepler20 import kepler20_system, paper_multi_transits
    spec = json.loads(sys.argv[1])
    system = kepler20_system()
    t = np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1 / 1440) for e in paper_multi_transits(system)])
    t = np.resize(t, spec["times"])  # repeats the windows beyond the grid's 2926 times
    alpha = np.linspace(0.0, 360.0, spec["alphas"], endpoint=False)
    cases = ("same", "opposite")[: spec["cases"]]
    if spec["draws"]:
        from jaxppo.obliquity._marginal import marginal_chi2
        rng = np.random.default_rng(0)
        systems = []
        for _ in range(spec["draws"]):
            pl = [p.replace(t0=p.t0 + rng.normal(0, 2e-4), radius=p.radius * (1 + rng.normal(0, 1e-3))) for p in system.planets]
            systems.append(system.replace(planets=pl))
        y, sig = np.ones(t.size), np.full(t.size, 1e-4)
        run = lambda: marginal_chi2(systems, t, 1, y, sig, alpha, cases)
        elements = spec["draws"] * len(cases) * alpha.size * t.size
    else:
        run = lambda: jp.sweep(system, t, alpha, cases)
        elements = len(cases) * alpha.size * t.size
    t0 = time.perf_counter(); run(); cold = time.perf_counter() - t0
    warm = []
    for _ in range(3):
        t0 = time.perf_counter(); run(); warm.append(time.perf_counter() - t0)
    warm = min(warm)
    hwm = [l for l in open("/proc/self/status") if l.startswith("VmHWM")][0]
    print(json.dumps(dict(spec, elements=elements, cold_s=cold, warm_s=warm, peak_mb=int(hwm.split()[1]) / 1024)))
""")

DEVICE_CHILD = textwrap.dedent(r"""
    import json, sys, time
    import jax
    jax.config.update("jax_enable_x64", True)
    import numpy as np
    import jaxppo as jp
    import jaxppo.model._plan
    from jaxppo.model._kepler20 import kepler20_system, paper_multi_transits
    n = int(sys.argv[1])
    rng = np.random.default_rng(0)
    x1, y1 = rng.uniform(-0.9, 0.9, n), rng.uniform(-0.4, 0.4, n)
    r = rng.uniform(0.01, 0.1, (n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    sep = rng.uniform(np.abs(r[:, 0] - r[:, 1]) + 1e-3, r.sum(1))
    x = np.stack([x1, x1 + sep * np.cos(ang)], 1); y = np.stack([y1, y1 + sep * np.sin(ang)], 1)
    star = jp.kepler20_star()
    system = kepler20_system()
    t = np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1 / 1440) for e in paper_multi_transits(system)])
    alpha = np.arange(0.0, 360.0)
    out = {"devices": jax.device_count()}
    for name, fn in (("auto", lambda: jp.occultation_flux(star, x, y, r, chunk=16384)),
                     ("exact", lambda: jp.occultation_flux(star, x, y, r, method="exact", chunk=16384)),
                     ("sweep", lambda: jp.sweep(system, t, alpha))):
        np.asarray(fn())
        best = min(_t for _t in [(lambda s: (np.asarray(fn()), time.perf_counter() - s)[1])(time.perf_counter()) for _ in range(3)])
        out[name] = best
    print(json.dumps(out))
""")


def child(code: str, arg: str, env=None) -> dict:
    env = dict(os.environ if env is None else env, PYTHONPATH=str(ROOT), JAXPPO_CACHE_DIR="", JAX_ENABLE_COMPILATION_CACHE="false")
    proc = subprocess.run([sys.executable, "-c", code, arg], capture_output=True, text=True, env=env, timeout=1800)
    if proc.returncode:
        raise RuntimeError(proc.stderr[-3000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


BASE = dict(times=2926, alphas=90, cases=2, draws=0)
AXES = {
    "times": [731, 2926, 11704, 23408, 46816],
    "alphas": [45, 180, 360, 720, 1440],
    "cases": [1, 2],
    "draws": [1, 4, 16, 32],
}


def axes(budget_gb: float, out_json: Path, figure: Path) -> None:
    import numpy as np

    done = json.loads(out_json.read_text()) if out_json.exists() else []  # resume
    for axis, values in AXES.items():
        for v in values:
            spec = dict(BASE, **{axis: v})
            if axis == "draws":
                spec["alphas"] = 45
            key = dict(spec, axis=axis)
            if any(all(row.get(k) == key[k] for k in key) for row in done):
                continue
            row = dict(child(CHILD, json.dumps(spec)), axis=axis, load=os.getloadavg()[0])
            done.append(row)
            out_json.write_text(json.dumps(done, indent=1))
            print(f"{axis:7s} {v:6d}: {row['elements']:>12,d} elements  warm {row['warm_s']:7.3f} s  cold {row['cold_s']:6.2f} s  "
                  f"peak {row['peak_mb']:8.1f} MB  [load {row['load']:.1f}]", flush=True)
    lines = ["| axis | sizes | elements | warm time [s] | peak memory [MB] | memory per element [bytes] | "
             f"largest grid in {budget_gb:g} GB (extrapolated) |", "|---|---|---|---|---|---|---|"]
    fits = {}
    for axis in AXES:
        rows = sorted((r for r in done if r["axis"] == axis), key=lambda r: r["elements"])
        e = np.array([r["elements"] for r in rows], float)
        m = np.array([r["peak_mb"] for r in rows])
        slope, icpt = np.polyfit(e, m, 1) if len(rows) > 1 else (m[0] / e[0], 0.0)
        fits[axis] = (slope, icpt)
        if m[-1] - m[0] < 10.0:  # below the noise of a process's resident memory
            per, largest = "below noise", "not resolved"
        else:
            per, largest = f"{slope * 2**20:.0f}", f"{(budget_gb * 1024 - icpt) / slope:.2e} elements"
        lines.append(f"| {axis} | {', '.join(str(r[axis]) for r in rows)} | {int(e[0]):,}-{int(e[-1]):,} | "
                     f"{rows[0]['warm_s']:.3f}-{rows[-1]['warm_s']:.3f} | {m[0]:.0f}-{m[-1]:.0f} | "
                     f"{per} | {largest} |")
    print("\n".join(lines))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for axis in AXES:
        rows = sorted((r for r in done if r["axis"] == axis), key=lambda r: r["elements"])
        e = [r["elements"] for r in rows]
        ax[0].loglog(e, [r["warm_s"] for r in rows], "o-", label=axis)
        ax[1].loglog(e, [r["peak_mb"] for r in rows], "o-", label=axis)
    ax[0].set_xlabel("grid elements (draws x cases x alphas x times)")
    for a in ax:
        a.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax[0].set_ylabel("warm time [s]")
    ax[1].set_xlabel("grid elements (draws x cases x alphas x times)")
    ax[1].set_ylabel("peak resident memory [MB]")
    for a in ax:
        a.legend(title="growing axis")
        a.grid(alpha=0.3, which="both")
    fig.suptitle("Kepler-20 b + c obliquity grid: each axis grown from 2 cases x 90 alphas x 2926 times (draws: 45 alphas)")
    fig.tight_layout()
    fig.savefig(figure, dpi=110)
    print(f"wrote {figure} and {out_json} (the table above goes into docs/scale.md)")


def devices(frames: int) -> None:
    for n in (1, 2, 4):
        env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={n}", JAX_PLATFORMS="cpu")
        row = child(DEVICE_CHILD, str(frames), env)
        print(f"{row['devices']} device(s): auto {row['auto']:.3f} s, exact {row['exact']:.3f} s ({frames} overlapping pairs); "
              f"sweep (Kepler-20 grid, 2 x 360 x 2926) {row['sweep']:.3f} s  [load {os.getloadavg()[0]:.1f}, "
              f"{os.cpu_count()} cores, affinity {len(os.sched_getaffinity(0))}]", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["axes", "devices"])
    ap.add_argument("--budget-gb", type=float, default=24.0)
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--out", type=Path, default=Path("scale_points.json"), help="the measured points (JSON; resumed from)")
    ap.add_argument("--figure", type=Path, default=ROOT / "docs" / "scale.png", help="the chart (default: docs/scale.png)")
    args = ap.parse_args()
    axes(args.budget_gb, args.out, args.figure) if args.what == "axes" else devices(args.frames)


if __name__ == "__main__":
    main()
