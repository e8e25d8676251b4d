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
    """A light curve binned in rotation chunks and rotational phase (paper Fig. 3).

    Made by ``brightness_map``; drawn by ``plot_brightness_map``.
    Row k is chunk k (t_ref + k P <= t < t_ref + (k + 1) P); its bins outside
    [0, 1) repeat the neighbouring chunks' data.

    Attributes
    ----------
    period : float
        Rotation period [d] = chunk length.
    t_ref : float
        Start of chunk 0 [d].
    chunk_start : numpy.ndarray
        Start time of each chunk [d], shape [n_chunk].
    phase_edges : numpy.ndarray
        Phase bin edges from about -extend to 1 + extend, shape [n_bin + 1];
        0 and 1 are edges.
    flux : numpy.ndarray
        Mean relative flux per phase bin [%], shape [n_chunk, n_bin]; NaN
        where a bin has fewer than ``min_points`` points.
    counts : numpy.ndarray
        Points per bin, shape [n_chunk, n_bin] (int).
    repeated : numpy.ndarray
        True for bins outside [0, 1) (the shaded, repeated parts), shape
        [n_bin].

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.arange(0.0, 40.0, 0.05)
    >>> bmap = jp.activity.brightness_map(t, 1e-3 * np.sin(2 * np.pi * t / 10.0), period=10.0, bins=25)
    >>> bmap.flux.shape, bmap.chunk_start.tolist(), int(bmap.repeated.sum())
    ((4, 49), [0.0, 10.0, 20.0, 30.0], 24)
    >>> print(f"{bmap.phase_edges[0]:.2f} .. {bmap.phase_edges[-1]:.2f}")
    -0.48 .. 1.48
    """

    period: float
    t_ref: float
    chunk_start: np.ndarray
    phase_edges: np.ndarray
    flux: np.ndarray
    counts: np.ndarray
    repeated: np.ndarray

    @property
    def phase_centres(self) -> np.ndarray:
        """Centres of the phase bins, shape [n_bin] (mid-points of ``phase_edges``)."""
        return 0.5 * (self.phase_edges[1:] + self.phase_edges[:-1])


def brightness_map(time, flux, period: float, t_ref: float | None = None, bins: int = 50,
                   extend: float = 0.5, min_points: int = 3) -> BrightnessMap:
    """Bin a light curve into rotation chunks (the brightness map, paper Fig. 3).

    Chunk k holds t_ref + k P <= t < t_ref + (k + 1) P at phases
    (t - t_ref) / P - k in [0, 1); its row also shows phases in
    [-extend, 0) and [1, 1 + extend) from the neighbouring chunks, so that
    the modulation is not cut at the chunk edges. Bins have width 1/bins
    and 0 and 1 are bin edges (``extend`` is rounded to whole bins).

    Parameters
    ----------
    time : array_like
        Times [d], shape [n_times], finite.
    flux : array_like
        Relative flux (0 = mean level, e.g. ``PreparedLightCurve.flux``),
        shape [n_times], finite.
    period : float
        Rotation period [d] = chunk length.
    t_ref : float, optional
        Start of chunk 0 [d]; None (default): the first time.
    bins : int, optional
        Phase bins per rotation, >= 4 (default 50).
    extend : float, optional
        Repeated fraction of a rotation on each side, in [0, 1] (default 0.5,
        as in the paper).
    min_points : int, optional
        Bins with fewer points than this are NaN (default 3).

    Returns
    -------
    BrightnessMap
        The binned map, flux in percent.

    Raises
    ------
    ValueError
        If ``time`` and ``flux`` are not 1D of equal, non-zero length or not
        finite; if ``period`` is not a positive number; if ``bins`` is not an
        integer >= 4, ``extend`` outside [0, 1], ``min_points`` not a
        positive integer, or ``t_ref`` not finite.

    Examples
    --------
    A 0.1 % sinusoid of period 10 d: each chunk's minimum lies at phase 0.75.

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.arange(0.0, 40.0, 0.05)
    >>> bmap = jp.activity.brightness_map(t, 1e-3 * np.sin(2 * np.pi * t / 10.0), period=10.0, bins=25)
    >>> bmap.flux.shape  # 4 chunks, 25 bins + 12 repeated on each side
    (4, 49)
    >>> own = ~bmap.repeated
    >>> row = bmap.flux[1, own]
    >>> print(f"phase {bmap.phase_centres[own][np.argmin(row)]:.2f}: {row.min():.3f} %")
    phase 0.74: -0.099 %
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
    """Write a brightness map as a PNG (paper Fig. 3).

    Bright = high flux (colour scale symmetric about 0, to the 99th
    percentile of |flux|); the repeated parts outside [0, 1) are shaded,
    bins without data grey.

    Parameters
    ----------
    bmap : BrightnessMap
        The map from ``brightness_map``.
    path : str or os.PathLike
        The PNG file to write.
    title : str, optional
        Figure title; None (default): the period and a legend of the shading.
    spots : list of tuple, optional
        (time [d], phase, radius [deg]) of spots drawn as black dots (area
        proportional to the spot's), e.g. from ``fit_spots`` with phase
        = longitude / 360; copies are drawn in the repeated parts.

    Returns
    -------
    str or os.PathLike
        ``path``, as given.

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.arange(0.0, 40.0, 0.05)
    >>> bmap = jp.activity.brightness_map(t, 1e-3 * np.sin(2 * np.pi * t / 10.0), period=10.0, bins=25)
    >>> print(jp.activity.plot_brightness_map(bmap, "map.png", spots=[(15.0, 0.75, 5.0)]))
    map.png
    """
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
    """Write a PNG with the stitched light curve, the periodogram and the per-quarter variability.

    Three panels: the relative flux and its running median; the
    single-sinusoid periodogram (the two-harmonic one too when the period
    was doubled) with the period, its HWHM, the bootstrap range and
    optionally the paper's period; a bar chart of the variability.

    Parameters
    ----------
    prepared : PreparedLightCurve
        The light curve from ``prepare_light_curve``.
    rotation : RotationResult
        Its periodogram from ``rotation_period``.
    variability : dict
        {quarter: peak-to-peak [%]} from ``quarter_variability``.
    path : str or os.PathLike
        The PNG file to write.
    paper_period : float, optional
        A reference period [d] marked on the periodogram (e.g. 26.948 d of
        Mueller et al. 2021); None (default): none.

    Returns
    -------
    str or os.PathLike
        ``path``, as given.

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.arange(0.0, 60.0, 0.02)
    >>> q = np.where(t < 30.0, 1, 2)
    >>> prep = jp.activity.prepare_light_curve(t, 1 + 1e-3 * np.sin(2 * np.pi * t / 8.0), quarters=q,
    ...                                        mask_transits=False)
    >>> rot = jp.activity.rotation_period(prep.time, prep.flux, period_max=20.0)
    >>> var = jp.activity.quarter_variability(prep)
    >>> print(jp.activity.plot_periodogram(prep, rot, var, "periodogram.png"))
    periodogram.png
    """
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
    """Write a PNG of one chunk's relative flux with the few-spot model.

    Parameters
    ----------
    time : array_like
        Times of the chunk [d], shape [n_times].
    flux : array_like
        Relative flux of the chunk, shape [n_times] (plotted in percent).
    fit : SpotFit
        The fit from ``fit_spots``; its model is drawn on 1000 times
        spanning ``time``, and its longitudes and radii are in the title.
    path : str or os.PathLike
        The PNG file to write.

    Returns
    -------
    str or os.PathLike
        ``path``, as given.

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> fit = jp.activity.SpotFit(lon=np.array([90.0]), lat=np.array([0.0]), radius=np.array([5.0]),
    ...                           offset=0.0, contrast=0.59, inc=90.0, period=20.0, t_ref=0.0,
    ...                           chi2=0.0, sigma=1e-4, success=True)
    >>> t = np.linspace(0.0, 20.0, 200)
    >>> print(jp.activity.plot_spot_fit(t, fit.model(t), fit, "spots.png"))
    spots.png
    """
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
