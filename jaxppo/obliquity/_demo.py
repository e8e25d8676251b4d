"""The demo of ``jaxppo demo``: the paper's seven Kepler-20 b + c double
transits modelled for a few tilt angles, numbered as the scan numbers them."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..model._kepler20 import kepler20_system, paper_multi_transits
from ..model._processes import on_writer
from ..model._transits import alpha_limits
from ._config import load_config
from ._windows import scan_windows

__all__ = ["demo_events", "double_transit_demo"]


def demo_events(system):
    """The paper's seven double transits and their numbers as `jaxppo scan`
    of the bundled real data gives them (1, 2, ... over the multi-transits
    with data, summary.json ``multi_transits``), so that "transit 4" is the
    same event in the demo and in the scan's figures."""
    events = paper_multi_transits(system)
    by_mid = {round(w.event.mid, 2): w.number for w in scan_windows(load_config())}
    return events, [by_mid[round(ev.mid, 2)] for ev in events]


def _refuse_foreign_summary(out: Path) -> None:
    """ValueError when ``out`` holds a summary.json that is not a demo's (no
    ``event_numbers``), or a scan's folder (its finished-scan marker)."""
    summ = out / "summary.json"
    if not summ.exists():
        return
    try:
        ours = "event_numbers" in json.loads(summ.read_text())
    except (OSError, ValueError, TypeError):
        ours = False
    if not ours or (out / "scan_progress.jsonl").exists():
        raise ValueError(f"--out {out} holds a summary.json the demo did not write (a scan's folder?); the demo "
                         "writes its own there: use another folder")


def double_transit_demo(out) -> dict:
    """Light curves of the seven Kepler-20 b + c double transits for a few tilt
    angles, both hemisphere cases: ``out``/kepler20_double_transits.png and
    .csv, and summary.json (events with the scan's numbers, alphas, alpha
    limits, ``points``, ``seconds``), which it returns. A summary.json in
    ``out`` that the demo did not write (a scan's, or the user's) is a
    ValueError: the demo never replaces it."""
    on_writer(f"checking {out}", lambda: _refuse_foreign_summary(Path(out)))  # process 0 (of several) writes
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    system = kepler20_system()
    events, number = demo_events(system)
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
                rows += [(case, number[ei], a, ti, fi) for ti, fi in zip(t, flux[ai])]
            ax.set_title(f"{case}: transit {number[ei]}, BKJD {ev.mid:.2f}", fontsize=8)
            ax.set_xlabel("hours from mid")
    axes[0, 0].set_ylabel("flux - 1 [ppm]")
    axes[1, 0].set_ylabel("flux - 1 [ppm]")
    axes[0, 0].legend(title="alpha [deg]", fontsize=6)
    fig.tight_layout()
    elapsed = time.perf_counter() - t0
    summary = {"events": [dict(e.as_dict(), number=n) for e, n in zip(events, number)],
               "event_numbers": "as in jaxppo scan of the bundled real data (summary.json multi_transits)",
               "alphas": alphas.tolist(), "seconds": elapsed,
               "alpha_limits": list(alpha_limits(system)), "points": len(rows)}

    def write():
        fig.savefig(out / "kepler20_double_transits.png", dpi=110)
        with open(out / "kepler20_double_transits.csv", "w") as fh:
            fh.write("case,event,alpha,time,flux\n")
            for r in rows:
                fh.write(f"{r[0]},{r[1]},{r[2]:.1f},{r[3]:.6f},{r[4]:.12f}\n")
        (out / "summary.json").write_text(json.dumps(summary, indent=2))

    try:  # every process computes the curves (their frames span all processes' devices); process 0 writes
        on_writer(f"writing the demo into {out}", write)
    finally:
        plt.close(fig)
    return summary
