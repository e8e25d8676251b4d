"""Brightness map of a rotating star (Mueller et al. 2021, Sect. 2.4 and
Fig. 3): the light curve cut into chunks of one rotation period, flux
colour-coded against rotational phase (x) and time (y). Each row also shows
the second half of the previous chunk at phase < 0 and the first half of
the next one at phase > 1, shaded, so that the modulation is not cut at the
chunk edges."""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["BrightnessMap", "brightness_map", "plot_brightness_map", "plot_periodogram", "plot_spot_fit"]


@dataclasses.dataclass(frozen=True)
class BrightnessMap:
    """period [d]; t_ref [d]: start of chunk 0; chunk_start [d] (n_chunk,);
    phase_edges (n_bin + 1,) from -extend to 1 + extend; flux [%]
    (n_chunk, n_bin): mean relative flux per phase bin in percent, NaN where
    there is no data; counts (n_chunk, n_bin); repeated (n_bin,): True for
    bins outside [0, 1) (the shaded, repeated parts)."""

    period: float
    t_ref: float
    chunk_start: np.ndarray
    phase_edges: np.ndarray
    flux: np.ndarray
    counts: np.ndarray
    repeated: np.ndarray

    @property
    def phase_centres(self) -> np.ndarray:
        return 0.5 * (self.phase_edges[1:] + self.phase_edges[:-1])


def brightness_map(time, flux, period: float, t_ref: float | None = None, bins: int = 50,
                   extend: float = 0.5, min_points: int = 3) -> BrightnessMap:
    """Bin a light curve into rotation chunks.

    Args:
        time [d], flux (relative, 0 = mean): 1D, finite.
        period: rotation period [d] = chunk length.
        t_ref: start of chunk 0 [d]; default the first time.
        bins: phase bins per rotation.
        extend: repeated fraction of a rotation on each side (paper: 0.5).
        min_points: fewer points than this in a bin give NaN.
    Chunk k holds t_ref + k P <= t < t_ref + (k + 1) P at phases
    (t - t_ref) / P - k in [0, 1); its row also shows phases in
    [-extend, 0) and [1, 1 + extend) from the neighbouring chunks.
    """
    t = np.asarray(time, float)
    y = np.asarray(flux, float)
    if t.ndim != 1 or t.size == 0 or y.shape != t.shape:
        raise ValueError(f"time and flux must be 1D of equal, non-zero length, got {t.shape}, {y.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("time and flux must be finite")
    try:
        period = float(period)
    except (TypeError, ValueError):
        raise ValueError(f"period must be a number of days, got {period!r}") from None
    if not (np.isfinite(period) and period > 0):
        raise ValueError(f"period must be > 0 days, got {period!r}")
    if not isinstance(bins, (int, np.integer)) or bins < 4:
        raise ValueError(f"bins must be an integer >= 4, got {bins!r}")
    if not (0 <= extend <= 1):
        raise ValueError(f"extend must be in [0, 1], got {extend!r}")
    if not isinstance(min_points, (int, np.integer)) or min_points < 1:
        raise ValueError(f"min_points must be a positive integer, got {min_points!r}")
    t_ref = float(t.min()) if t_ref is None else float(t_ref)
    if not np.isfinite(t_ref):
        raise ValueError(f"t_ref must be finite, got {t_ref!r}")
    n_chunk = int(np.floor((t.max() - t_ref) / period)) + 1
    # bins of width 1/bins aligned so that 0 and 1 are bin edges
    n_ext = int(round(extend * bins))
    edges = np.arange(-n_ext, bins + n_ext + 1) / bins
    phase_all = (t - t_ref) / period
    total = np.zeros((n_chunk, edges.size - 1))
    counts = np.zeros_like(total)
    for k in range(n_chunk):
        ph = phase_all - k
        sel = (ph >= edges[0]) & (ph < edges[-1])
        idx = np.clip(np.searchsorted(edges, ph[sel], side="right") - 1, 0, edges.size - 2)
        np.add.at(total[k], idx, y[sel])
        np.add.at(counts[k], idx, 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(counts >= min_points, total / counts, np.nan)
    centres = 0.5 * (edges[1:] + edges[:-1])
    return BrightnessMap(period, t_ref, t_ref + period * np.arange(n_chunk), edges, 100.0 * mean,
                         counts.astype(int), (centres < 0) | (centres > 1))


def plot_brightness_map(bmap: BrightnessMap, path, title: str | None = None, spots=None):
    """Write the map as a PNG (paper Fig. 3). Bright = high flux. ``spots``:
    optional list of (time [d], phase, radius [deg]) drawn as black dots."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 7.5), constrained_layout=True)
    y_edges = np.append(bmap.chunk_start, bmap.chunk_start[-1] + bmap.period)
    finite = bmap.flux[np.isfinite(bmap.flux)]
    lim = float(np.percentile(np.abs(finite), 99)) if finite.size else 1.0
    mesh = ax.pcolormesh(bmap.phase_edges, y_edges, bmap.flux, cmap="inferno", vmin=-lim, vmax=lim,
                         shading="flat")
    lo, hi = bmap.phase_edges[0], bmap.phase_edges[-1]
    for a, b in ((lo, 0.0), (1.0, hi)):
        if b > a:
            ax.axvspan(a, b, facecolor="white", alpha=0.5, edgecolor="none", zorder=2)
    for x in (0.0, 1.0):
        ax.axvline(x, color="0.2", lw=0.8, zorder=3)
    if spots:
        # dot area proportional to the spot area (radius [deg]); repeated
        # copies in the shaded parts keep spots near phase 0 or 1 visible
        for ts, ph, rad in spots:
            for shift in (-1.0, 0.0, 1.0):
                x = ph + shift
                if lo <= x <= hi:
                    ax.scatter([x], [ts], s=3.0 * rad**2, facecolor="k", edgecolor="w", linewidth=0.3,
                               zorder=4, alpha=1.0 if shift == 0 else 0.5)
    ax.set_xlim(lo, hi)
    ax.set_ylim(y_edges[0], y_edges[-1])
    ax.set_facecolor("0.6")  # gaps in the data (grey, unlike any colour of the map)
    ax.set_xlabel("rotational phase")
    ax.set_ylabel("time of chunk start [BKJD]")
    ax.set_title(title or f"brightness map, chunks of P = {bmap.period:.3f} d\n"
                 "(shaded: repeated halves of the neighbouring chunks; grey: no data)", fontsize=10)
    cb = fig.colorbar(mesh, ax=ax, pad=0.02)
    cb.set_label("relative flux [%]")
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def plot_periodogram(prepared, rotation, variability: dict, path, paper_period: float | None = None):
    """Write a PNG with the stitched light curve, the periodogram and the
    per-quarter variability."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(3, 1, figsize=(8, 9), constrained_layout=True)
    ax = axes[0]
    ax.plot(prepared.time, 100 * prepared.flux, ",", color="0.6", rasterized=True)
    ax.plot(prepared.time, 100 * prepared.smooth, ".", ms=0.6, color="C3", rasterized=True)
    ax.set_xlabel("time [BKJD]")
    ax.set_ylabel("relative flux [%]")
    ax.set_title("stitched light curve (transits masked, outliers dropped)")
    ax = axes[1]
    ax.plot(1.0 / rotation.frequency, rotation.power, lw=0.7, color="k", label="GLS, one sinusoid", zorder=3)
    if rotation.doubled:
        ax.plot(1.0 / rotation.frequency, rotation.power2, lw=0.6, color="C1", alpha=0.8,
                label="GLS, two harmonics", zorder=2)
    if rotation.bootstrap is not None:
        ax.axvspan(rotation.bootstrap[0], rotation.bootstrap[2], color="C0", alpha=0.12, zorder=1,
                   label=f"quarter bootstrap 16-84 %: {rotation.bootstrap[0]:.1f}-{rotation.bootstrap[2]:.1f} d")
        ax.axvline(rotation.single_peak, color="C2", ls=":", lw=1,
                   label=f"one-sinusoid peak {rotation.single_peak:.3f} d")
    ax.axvline(rotation.period, color="C0", ls="--", lw=1,
               label=f"P = {rotation.period:.3f} +- {rotation.period_err:.3f} d (HWHM)")
    if paper_period is not None:
        ax.axvline(paper_period, color="C3", ls="-.", lw=1, label=f"paper {paper_period} d")
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xticks([2, 3, 5, 7, 10, 14, 20, 27, 40])
    ax.set_xlabel("period [d]")
    ax.set_ylabel("GLS power")
    ax.legend(fontsize=8, loc="upper left")
    ax = axes[2]
    keys = list(variability)
    ax.bar(range(len(keys)), [variability[k] for k in keys], color="C0")
    ax.set_xticks(range(len(keys)), keys)
    ax.set_xlabel("quarter")
    ax.set_ylabel("peak-to-peak [%]")
    ax.set_title("variability per quarter (1st-99th percentile of the smoothed curve)")
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def plot_spot_fit(time, flux, fit, path):
    """Write a PNG of one chunk's relative flux with the few-spot model."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(time, float)
    tm = np.linspace(t.min(), t.max(), 1000)
    fig, ax = plt.subplots(figsize=(7, 3.6), constrained_layout=True)
    ax.plot(t, 100 * np.asarray(flux), ".", ms=2, color="0.6", label="data")
    ax.plot(tm, 100 * fit.model(tm), color="C3", lw=1.5, label=f"{fit.lon.size} spots, contrast {fit.contrast:.2f}")
    desc = ", ".join(f"{lo:.0f} deg / {r:.1f} deg" for lo, r in zip(fit.lon, fit.radius))
    ax.set_title(f"spot inversion: longitude / radius = {desc}", fontsize=9)
    ax.set_xlabel("time [BKJD]")
    ax.set_ylabel("relative flux [%]")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path
