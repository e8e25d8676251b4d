"""Speed against accuracy of every method, measured in one process.

Scenes: Kepler-20-like frames (p = 0.018 and 0.029, PPOs and separate disks,
ingress/egress included) on the PHOENIX-based star (non-linear P100). Error:
max |flux - exact| over the scenes; time: per frame, batched, warm (the
analytic methods and the peers on the scenes repeated 64 times, so per-call
overheads do not count; the rasters on the scenes once).

    python benchmarks/speed_accuracy.py [--frames 400] [--out docs]

Writes OUT/speed_accuracy.csv, OUT/speed_accuracy.png (error vs time per
frame, log-log) and OUT/failure_modes.png (error against distance to a contact
point, against planet size, and in float32).
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402
from jaxppo import RasterSettings  # noqa: E402


def scenes(n, rng):
    x1 = rng.uniform(-1.0, 1.0, n)
    y1 = rng.uniform(-0.5, 0.5, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    sep = rng.uniform(0.0, 0.08, n)
    x = np.stack([x1, x1 + sep * np.cos(ang)], 1)
    y = np.stack([y1, y1 + sep * np.sin(ang)], 1)
    r = np.tile([0.018, 0.029], (n, 1))
    return x, y, r


def timed(fn, repeat=3):
    fn()
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=400)
    ap.add_argument("--out", default="docs")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    star = jp.kepler20_star()
    x, y, r = scenes(args.frames, rng)
    n = x.shape[0]
    exact = np.asarray(jp.occultation_flux(star, x, y, r, method="exact", order=48))
    rows = []

    # The analytic methods are also timed on the scenes repeated 64 times:
    # per-frame costs at scale, without per-call overheads.
    big = tuple(np.tile(v, (64, 1)) for v in (x, y, r))

    def add(method, setting, fn, scaled=None):
        t = timed(lambda: np.asarray(fn()))
        err = float(np.max(np.abs(np.asarray(fn()) - exact)))
        us = t / n * 1e6
        if scaled is not None:
            us = timed(lambda: np.asarray(scaled())) / big[0].shape[0] * 1e6
        rows.append((method, setting, err, us))
        print(f"{method:22s} {setting:28s} max error {err:9.2e}   {us:12.2f} us/frame", flush=True)

    for order in (8, 12, 16, 24):
        add("exact", f"order {order}", lambda order=order: jp.occultation_flux(star, x, y, r, method="exact", order=order),
            lambda order=order: jp.occultation_flux(star, *big, method="exact", order=order))
    add("auto", "lens tiers / order 24", lambda: jp.occultation_flux(star, x, y, r, method="auto"),
        lambda: jp.occultation_flux(star, *big, method="auto"))
    for nn in (128, 256, 500, 1000, 2000):
        add("raster full-disk", f"N={nn}, 1x1", lambda nn=nn: jp.occultation_flux(star, x, y, r, method="raster", raster=RasterSettings("full", n=nn, ss=1)))
    for nn in (256, 500):
        add("raster full-disk", f"N={nn}, edge AA", lambda nn=nn: jp.occultation_flux(star, x, y, r, method="raster", raster=RasterSettings("full", n=nn, aa="edge")))
        add("raster full-disk", f"N={nn}, 2x2", lambda nn=nn: jp.occultation_flux(star, x, y, r, method="raster", raster=RasterSettings("full", n=nn, ss=2)))
    for div in (4, 8, 16, 24):
        add("raster window", f"p/{div}, exact coverage", lambda div=div: jp.occultation_flux(star, x, y, r, method="raster", raster=RasterSettings(scale=0.018 / div)))
        add("raster window", f"p/{div}, 4x4 supersample", lambda div=div: jp.occultation_flux(star, x, y, r, method="raster", raster=RasterSettings(scale=0.018 / div, aa="supersample", ss=4)))

    # Peers on the same scenes, quadratic law (their law): error against our
    # exact engine for that law.
    quad = jp.Star.quadratic(0.495, 0.154)
    ex_q = np.asarray(jp.occultation_flux(quad, x, y, r, method="exact", order=48))
    try:
        from batman import _quadratic_ld

        d = np.hypot(x, y)

        def bat(d=d):
            return 1 - ((1 - _quadratic_ld._quadratic_ld(d[:, 0], 0.018, 0.495, 0.154, 1)) + (1 - _quadratic_ld._quadratic_ld(d[:, 1], 0.029, 0.495, 0.154, 1)))

        t = timed(lambda: bat(np.tile(d, (64, 1)))) / 64
        err = float(np.max(np.abs(bat() - ex_q)))
        rows.append(("batman (sum of 1-disk)", "quadratic", err, t / n * 1e6))
        print(f"{'batman':22s} {'sum of single disks':28s} max error {err:9.2e}   {t / n * 1e6:12.2f} us/frame")
    except ImportError:
        print("batman not installed")
    try:
        from gefera.phot import flux_ng

        bp = np.hypot(x[:, 0], y[:, 0])
        bpm = np.hypot(x[:, 1] - x[:, 0], y[:, 1] - y[:, 0])
        v = np.stack([-x[:, 0], -y[:, 0]], 1)
        w = np.stack([x[:, 1] - x[:, 0], y[:, 1] - y[:, 0]], 1)
        th = np.arccos(np.clip(np.sum(v * w, 1) / np.linalg.norm(v, axis=1) / np.maximum(np.linalg.norm(w, axis=1), 1e-300), -1, 1))

        def gef(reps=1):
            args = (np.tile(v, reps) for v in (bp, bpm, np.cos(th), np.sin(th)))
            return 1 + flux_ng(0.495, 0.154, 0.018, 0.029, *args)

        t = timed(lambda: gef(64)) / 64
        g = gef()
        ok = np.isfinite(g)
        err = float(np.max(np.abs(g[ok] - ex_q[ok])))
        rows.append(("gefera (pairs)", "quadratic", err, t / n * 1e6))
        print(f"{'gefera':22s} {'exact pairs, quadratic':28s} max error {err:9.2e}   {t / n * 1e6:12.2f} us/frame"
              f"   ({(~ok).sum()} of {n} frames NaN: concentric or off-star pairs, outside its domain)")
    except ImportError:
        print("gefera not installed")

    with open(out / "speed_accuracy.csv", "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["method", "setting", "max_abs_error", "us_per_frame"])
        wr.writerows(rows)

    fig, ax = plt.subplots(figsize=(7.5, 5))
    markers = {"exact": "o", "auto": "*", "raster full-disk": "s", "raster window": "D"}
    for m in dict.fromkeys(row[0] for row in rows):
        sel = [row for row in rows if row[0] == m]
        ax.loglog([row[3] for row in sel], [max(row[2], 1e-17) for row in sel], markers.get(m, "^"), label=m, ms=7)
        for row in sel:
            ax.annotate(row[1], (row[3], max(row[2], 1e-17)), fontsize=6, xytext=(3, 3), textcoords="offset points")
    ax.axhline(1e-10, color="0.6", ls=":", lw=0.8)
    ax.set_xlabel("time per frame [us] (2-core CPU, float64, batched)")
    ax.set_ylabel("max |flux - exact|")
    ax.set_title("Kepler-20-like scenes (PPOs, limb crossings), PHOENIX-based star; peers: quadratic law", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "speed_accuracy.png", dpi=120)
    plt.close(fig)

    # Where methods fail.
    fig, axs = plt.subplots(1, 3, figsize=(13, 3.8))
    eps = np.logspace(-14, -1, 27)
    base = np.array([0.3, 0.1])
    errs = {}
    for label, mk in (("exact", lambda: dict(method="exact")), ("raster window p/16", lambda: dict(method="raster", raster=RasterSettings(scale=0.03 / 16)))):
        e_tan = []
        for e in eps:
            xx = np.array([[base[0], base[0] + 0.05 + e]])  # outer tangency of p = 0.03 and 0.02
            yy = np.array([[base[1], base[1]]])
            rr = np.array([[0.03, 0.02]])
            ref = 1 - (2 - float(jp.occultation_flux(star, xx[:, :1], yy[:, :1], rr[:, :1], order=48)[0]) - float(jp.occultation_flux(star, xx[:, 1:], yy[:, 1:], rr[:, 1:], order=48)[0]))
            e_tan.append(abs(float(jp.occultation_flux(star, xx, yy, rr, **mk())[0]) - ref))
        errs[label] = e_tan
        axs[0].loglog(eps, np.maximum(e_tan, 1e-17), "o-", ms=3, label=label)
    axs[0].set_xlabel("distance from outer tangency [R*]")
    axs[0].set_ylabel("|error|")
    axs[0].legend(fontsize=7)
    ps = np.logspace(-4, np.log10(0.5), 12)
    for label, kw in (("exact order 24", dict(method="exact")), ("exact order 12", dict(method="exact", order=12)), ("raster window default", dict(method="raster"))):
        e_p = []
        for p in ps:
            xx = np.array([[0.95, 0.95 + 0.8 * p]])
            yy = np.array([[0.1, 0.1 + 0.3 * p]])
            rr = np.array([[p, 0.7 * p]])
            ref = float(jp.occultation_flux(star, xx, yy, rr, order=64)[0])
            e_p.append(abs(float(jp.occultation_flux(star, xx, yy, rr, **kw)[0]) - ref))
        axs[1].loglog(ps, np.maximum(e_p, 1e-17), "o-", ms=3, label=label)
    axs[1].set_xlabel("planet radius p (overlapping pair on the limb)")
    axs[1].legend(fontsize=7)
    x32 = x.astype(np.float32)
    star32 = jax.tree_util.tree_map(lambda v: v.astype(jnp.float32) if hasattr(v, "astype") else v, star)
    f32 = np.asarray(jp.occultation_flux(star32, x32, y.astype(np.float32), r.astype(np.float32), method="exact"), float)
    d = np.hypot(x[:, 0], y[:, 0])
    axs[2].semilogy(d, np.maximum(np.abs(f32 - exact), 1e-17), ".", ms=3)
    axs[2].set_xlabel("distance of the first disk from the centre")
    axs[2].set_title(f"float32 exact: max error {np.max(np.abs(f32 - exact)):.1e}", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "failure_modes.png", dpi=120)
    plt.close(fig)
    print(f"wrote {out / 'speed_accuracy.csv'}, {out / 'speed_accuracy.png'}, {out / 'failure_modes.png'}")


if __name__ == "__main__":
    main()
