"""Command line: ``jaxppo demo`` (and the workflows as they land)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def _enable_x64() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)


def kepler20_system(star=None):
    """Kepler-20 b (tilted) and c with the paper's Table 3 "This work" values
    (T0 converted to BKJD = BJD - 2454833)."""
    import jaxppo as jp

    star = jp.kepler20_star() if star is None else star
    b = jp.Planet(period=3.69611590, t0=134.501962, a=10.60, inc=87.687, radius=0.01805, name="b")
    c = jp.Planet(period=10.85408479, t0=138.608470, a=22.764, inc=89.967, radius=0.02878, name="c")
    return jp.System(star, [b, c], tilted=0)


def cmd_demo(args) -> int:
    """Light curves of the seven Kepler-20 b + c double transits for a few tilt
    angles, both hemisphere cases; writes a CSV and a figure."""
    _enable_x64()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import jaxppo as jp

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    system = kepler20_system()
    events = jp.multi_transits(system, 300.0, 1600.0)
    paper = (334.02, 670.45, 844.13, 1017.82, 1180.56, 1354.25, 1527.93)
    events = [min(events, key=lambda e: abs(e.mid - m)) for m in paper]
    alphas = np.array([0.0, 90.0, 151.0, 212.0, 249.0, 313.0, 322.0])
    t0 = time.perf_counter()
    rows = []
    fig, axes = plt.subplots(2, len(events), figsize=(3.0 * len(events), 5.5), sharey=True)
    for ci, case in enumerate(("same", "opposite")):
        for ei, ev in enumerate(events):
            t = np.arange(ev.start - 0.05, ev.end + 0.05, 1.0 / 1440.0)
            flux = np.asarray(system.flux(t, alpha=alphas, case=case))
            ax = axes[ci, ei]
            for ai, a in enumerate(alphas):
                ax.plot((t - ev.mid) * 24, (flux[ai] - 1) * 1e6, lw=0.8, label=f"{a:.0f}" if ei == 0 else None)
                rows += [(case, ev.number, a, ti, fi) for ti, fi in zip(t, flux[ai])]
            ax.set_title(f"{case}: BKJD {ev.mid:.2f}", fontsize=8)
            ax.set_xlabel("hours from mid")
    axes[0, 0].set_ylabel("flux - 1 [ppm]")
    axes[1, 0].set_ylabel("flux - 1 [ppm]")
    axes[0, 0].legend(title="alpha [deg]", fontsize=6)
    fig.tight_layout()
    fig.savefig(out / "kepler20_double_transits.png", dpi=110)
    elapsed = time.perf_counter() - t0
    with open(out / "kepler20_double_transits.csv", "w") as fh:
        fh.write("case,event,alpha,time,flux\n")
        for r in rows:
            fh.write(f"{r[0]},{r[1]},{r[2]:.1f},{r[3]:.6f},{r[4]:.12f}\n")
    summary = {"events": [e.as_dict() for e in events], "alphas": alphas.tolist(), "seconds": elapsed,
               "alpha_limits": list(jp.alpha_limits(system))}
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(f"wrote {out}/kepler20_double_transits.png, .csv and summary.json ({len(rows)} model points, {elapsed:.2f} s)")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="jaxppo", description="Planet-planet occultations in JAX")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("demo", help="Kepler-20 b + c double-transit light curves for a few tilt angles")
    p.add_argument("--out", default="jaxppo_demo", help="output folder")
    p.set_defaults(func=cmd_demo)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
