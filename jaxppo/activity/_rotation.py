"""Rotation period and variability of a spotted star from long photometry
(Mueller et al. 2021, Sects. 2.4 and 3.2).

Pipeline (each step documented in docs/activity.md):

1. stitch: every quarter (or gap-separated segment) is divided by its own
   median, because Kepler quarters sit on different detectors and levels;
2. mask the transits of the known planets (first to last contact plus a
   margin), so transits neither bias the smoothing nor the periodogram;
3. drop outliers: points further than ``clip`` robust sigmas (1.4826 MAD)
   from a running median of ``smooth`` cadences within their quarter;
4. generalised (floating-mean) Lomb-Scargle periodogram, astropy's
   ``LombScargle`` (Zechmeister & Kuerster 2009); its highest peak P1 is the
   period unless a two-harmonic model near 2 P1 wins a BIC test (a spot
   signal with two dips per rotation has most power at half the period);
5. period uncertainty: the half width at half maximum of the chosen peak,
   sigma_P = P^2 sigma_f; optionally also the spread of the peak over a
   bootstrap that resamples whole quarters (spot evolution);
6. peak-to-peak variability per quarter: 1st to 99th percentile of the
   running-median curve, in percent.
"""

from __future__ import annotations

import dataclasses
from importlib import resources
from pathlib import Path

import numpy as np

__all__ = [
    "PAPER_ROTATION_PERIOD",
    "PAPER_ROTATION_PERIOD_ERR",
    "PreparedLightCurve",
    "RotationResult",
    "load_kepler20_quarters",
    "read_quarters_csv",
    "prepare_light_curve",
    "transit_mask",
    "rotation_period",
    "quarter_variability",
]

# Mueller et al. (2021), Sect. 3.2.
PAPER_ROTATION_PERIOD = 26.948
"""Kepler-20's rotation period [d] of Mueller et al. (2021), Sect. 3.2
(+- 0.001 d, ``PAPER_ROTATION_PERIOD_ERR``)."""
PAPER_ROTATION_PERIOD_ERR = 0.001
KEPLER20_DATA = "kepler20_kic6850504_llc_q1-q17_pdcsap.csv.gz"


def _series(time, flux) -> tuple[np.ndarray, np.ndarray]:
    """time and flux as float arrays: 1D, at least 10 points, same shape."""
    t = np.asarray(time, float)
    f = np.asarray(flux, float)
    if t.ndim != 1 or t.size < 10:
        raise ValueError(f"time must be 1D with at least 10 points, got shape {t.shape}")
    if f.shape != t.shape:
        raise ValueError(f"flux must have the shape of time {t.shape}, got {f.shape}")
    return t, f


def _check_positive(name: str, value, strict: bool = True) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(v) or (v <= 0 if strict else v < 0):
        raise ValueError(f"{name} must be {'>' if strict else '>='} 0 and finite, got {value!r}")
    return v


def read_quarters_csv(path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Read a light curve CSV: time [d], flux (any unit) and an optional quarter label.

    Lines starting with ``#`` are comments; the first other line is the
    header, which names the columns (case-insensitive): time is the first of
    ``time``, ``time_bkjd``, ``bkjd``, ``t``; flux the first of ``flux``,
    ``pdcsap_flux``, ``sap_flux``, ``f``; the quarter label the first of
    ``quarter``, ``q``, ``segment`` (optional). Other columns are ignored.
    Empty fields read as NaN; rows with a non-finite time or flux are
    dropped. A ``.gz`` file is decompressed on the fly.

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file (``.csv`` or gzip-compressed ``.csv.gz``).

    Returns
    -------
    time : numpy.ndarray
        Times [d], shape [n_rows] (rows with finite time and flux only).
    flux : numpy.ndarray
        Fluxes in the file's unit, shape [n_rows].
    quarter : numpy.ndarray or None
        Quarter label per row, shape [n_rows] (float); None when the file has
        no quarter column.

    Raises
    ------
    ValueError
        If the file does not exist or cannot be read; if it has no header and
        data row; if no column is named as a time or a flux column; if a row
        is unreadable (not numbers) or has a different number of columns than
        the header.

    Examples
    --------
    >>> import jaxppo as jp
    >>> rows = ["# a Kepler-like light curve", "time,pdcsap_flux,quarter",
    ...         "131.51,1000.0,1", "131.53,,1", "131.55,1002.5,2"]
    >>> with open("lc.csv", "w") as fh:
    ...     for row in rows:
    ...         print(row, file=fh)
    >>> time, flux, quarter = jp.activity.read_quarters_csv("lc.csv")
    >>> print(time.tolist(), flux.tolist(), quarter.tolist())
    [131.51, 131.55] [1000.0, 1002.5] [1.0, 2.0]
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"data file not found: {path}")
    import gzip

    opener = gzip.open if path.suffix == ".gz" else open
    try:
        with opener(path, "rt") as fh:
            lines = [ln for ln in fh if ln.strip() and not ln.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"cannot read data file {path}: {err}") from err
    if len(lines) < 2:
        raise ValueError(f"data file {path} needs a header and at least one row")
    header = [h.strip().lower() for h in lines[0].split(",")]

    def col(names, required=True):
        for n in names:
            if n in header:
                return header.index(n)
        if required:
            raise ValueError(f"data file {path}: no column named any of {names}; header is {header}")
        return None

    it, i_f = col(("time", "time_bkjd", "bkjd", "t")), col(("flux", "pdcsap_flux", "sap_flux", "f"))
    iq = col(("quarter", "q", "segment"), required=False)
    try:
        data = np.array([[float(x) if x.strip() else np.nan for x in ln.split(",")] for ln in lines[1:]])
    except ValueError as err:
        raise ValueError(f"data file {path}: unreadable row ({err})") from err
    if data.ndim != 2 or data.shape[1] != len(header):
        raise ValueError(f"data file {path}: rows must have {len(header)} columns like the header")
    ok = np.isfinite(data[:, it]) & np.isfinite(data[:, i_f])
    q = None if iq is None else data[ok, iq]
    return data[ok, it], data[ok, i_f], q


def load_kepler20_quarters() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Load the bundled real Kepler-20 long-cadence PDCSAP light curve, quarters 1-17.

    KIC 6850504, the data of Mueller et al. (2021), Sect. 3.2; provenance in
    jaxppo/data/README.md. Read with ``read_quarters_csv`` (rows with a
    non-finite time or flux dropped).

    Returns
    -------
    time : numpy.ndarray
        Times [BKJD = BJD - 2454833 d], shape [n_points].
    flux : numpy.ndarray
        PDCSAP fluxes [e-/s], shape [n_points].
    quarter : numpy.ndarray
        Kepler quarter (1 to 17) of each point, shape [n_points] (float).

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> time, flux, quarter = jp.activity.load_kepler20_quarters()
    >>> time.size, np.unique(quarter).size
    (64792, 17)
    >>> print(f"{time.min():.2f} .. {time.max():.2f} BKJD")
    131.51 .. 1591.00 BKJD
    """
    path = resources.files("jaxppo") / "data" / KEPLER20_DATA
    with resources.as_file(path) as p:
        return read_quarters_csv(p)


def transit_mask(time, system, margin: float = 0.1) -> np.ndarray:
    """Mark the points outside every transit of a system's planets.

    Points within half the first-to-last-contact duration plus ``margin``
    of a mid-transit time are in transit. The margin covers a long-cadence
    exposure (0.02 d) and the ephemeris drift over the Kepler mission. This
    is the negation of ``jaxppo.model._overlap.in_transit_mask`` (the one
    in-transit mask of the library) with ``pad = margin``.

    Parameters
    ----------
    time : array_like
        Times [d], shape [n_times].
    system : jaxppo.System
        The planets whose transits are masked (their ephemerides, TTVs
        included).
    margin : float, optional
        Added to each half transit duration [d], >= 0 (default 0.1).

    Returns
    -------
    mask : numpy.ndarray of bool
        True where no planet transits, False in transit; shape [n_times].

    Raises
    ------
    ValueError
        If ``system`` is not a ``jaxppo.System``, or ``margin`` is
        negative, not finite or not a number.

    Examples
    --------
    >>> import jaxppo as jp
    >>> time, flux, quarter = jp.activity.load_kepler20_quarters()
    >>> keep = jp.activity.transit_mask(time, jp.kepler20_system())
    >>> keep.size, int((~keep).sum())  # points in a transit of Kepler-20 b or c
    (64792, 7184)
    """
    from ..model._overlap import in_transit_mask
    from ..model._system import System

    if not isinstance(system, System):
        raise ValueError(f"system must be a jaxppo.System, got {type(system).__name__}")
    margin = _check_positive("margin", margin, strict=False)
    return ~in_transit_mask(system, time, pad=margin)


def _segments(time: np.ndarray, gap: float) -> np.ndarray:
    """Segment labels 0, 1, ... starting a new one after every gap > ``gap`` [d]."""
    return np.concatenate([[0], np.cumsum(np.diff(time) > gap)])


def _running_median(y: np.ndarray, size: int) -> np.ndarray:
    from scipy.ndimage import median_filter

    return median_filter(y, size=min(size, y.size) | 1, mode="nearest")


@dataclasses.dataclass(frozen=True)
class PreparedLightCurve:
    """A stitched, transit-masked, outlier-clipped light curve.

    Made by ``prepare_light_curve``; the points are sorted in time.

    Attributes
    ----------
    time : numpy.ndarray
        Times [d], shape [n_kept].
    flux : numpy.ndarray
        Relative flux: each quarter divided by its median, minus 1 (0 = the
        quarter's median level), shape [n_kept].
    smooth : numpy.ndarray
        Running median of ``flux`` within each quarter, shape [n_kept].
    quarter : numpy.ndarray
        Quarter (or segment) label of each point, shape [n_kept].
    report : dict
        What was masked and clipped and why: ``points`` (input),
        ``non_finite``, ``in_transit``, ``outliers``, ``kept``, ``segments``
        (how the quarters were labelled), ``n_quarters``, ``scatter_ppm``
        (robust point scatter [ppm]) and ``rules`` (one line).

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.arange(0.0, 40.0, 0.02)
    >>> f = 1000.0 * (1 + 1e-3 * np.sin(2 * np.pi * t / 10.0))
    >>> prep = jp.activity.prepare_light_curve(t, f, mask_transits=False)
    >>> prep.time.shape == prep.flux.shape == prep.smooth.shape == prep.quarter.shape
    True
    >>> print(f"{prep.flux.max():.5f} {prep.report['kept']}")
    0.00100 2000
    """

    time: np.ndarray
    flux: np.ndarray
    smooth: np.ndarray
    quarter: np.ndarray
    report: dict


def _quarter_labels(t: np.ndarray, quarters, gap: float) -> tuple[np.ndarray, str]:
    """A label per point (``quarters``, or segments split at gaps > ``gap``
    [d]) and how they were made."""
    if quarters is None:
        order = np.argsort(t, kind="stable")
        q = np.empty(t.size)
        q[order] = _segments(t[order], gap)
        return q, f"segments split at gaps > {gap} d"
    q = np.asarray(quarters, float)
    if q.shape != t.shape:
        raise ValueError(f"quarters must have the shape of time {t.shape}, got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("quarters must be finite labels")
    return q, "quarter labels given"


def _relative_flux(f: np.ndarray, q: np.ndarray, good: np.ndarray) -> np.ndarray:
    """f / median - 1 per quarter (its own flux level), NaN where not ``good``."""
    rel = np.full(f.shape, np.nan)
    for qv in np.unique(q[good]):
        m = good & (q == qv)
        med = np.median(f[m])
        if not med > 0:
            raise ValueError(f"flux of quarter {qv:g} has median {med}; fluxes must be positive")
        rel[m] = f[m] / med - 1.0
    return rel


def _quarter_running_median(y: np.ndarray, q: np.ndarray, smooth: int) -> np.ndarray:
    """The running median of ``smooth`` cadences within each quarter."""
    out = np.empty_like(y)
    for qv in np.unique(q):
        m = q == qv
        out[m] = _running_median(y[m], smooth)
    return out


def prepare_light_curve(time, flux, quarters=None, system=None, mask_transits: bool = True,
                        margin: float = 0.1, gap: float = 0.5, smooth: int = 25,
                        clip: float = 5.0) -> PreparedLightCurve:
    """Stitch quarters, mask transits and drop outliers.

    Steps 1-3 of the rotation pipeline (Mueller et al. 2021, Sect. 3.2):

    1. every quarter (or gap-separated segment) is divided by its own median
       and 1 subtracted, because Kepler quarters sit on different detectors
       and levels;
    2. the transits of the known planets are masked (first to last contact
       plus ``margin``; see ``transit_mask``);
    3. outliers are dropped: points further than ``clip`` robust sigmas
       (1.4826 MAD) from a running median of ``smooth`` cadences within their
       quarter. The running median is then recomputed without them.

    Parameters
    ----------
    time : array_like
        Times [d], shape [n_times], finite, at least 10 points.
    flux : array_like
        Fluxes (any positive unit), shape [n_times]; non-finite values are
        dropped.
    quarters : array_like, optional
        A label per point (e.g. the Kepler quarter), shape [n_times]. None
        (default): segments split at gaps longer than ``gap`` (this also
        splits Kepler's monthly downlinks, so periods longer than a segment
        are lost).
    system : jaxppo.System, optional
        The system whose transits are masked; None (default): Kepler-20 b
        and c (``jaxppo.kepler20_system``).
    mask_transits : bool, optional
        False keeps the transits in (default True).
    margin : float, optional
        Added to each half transit duration [d] (default 0.1).
    gap : float, optional
        Segment-splitting gap [d] when ``quarters`` is None (default 0.5).
    smooth : int, optional
        Running-median window [cadences] (default 25 long cadences = 12.3 h,
        much shorter than a rotation, longer than a transit).
    clip : float, optional
        Outlier threshold in robust sigmas (1.4826 MAD of the residuals from
        the running median; default 5).

    Returns
    -------
    PreparedLightCurve
        The kept points sorted in time: relative flux, its running median,
        the quarter labels and a report of what was dropped.

    Raises
    ------
    ValueError
        If ``time`` is not 1D with at least 10 finite points, ``flux`` has
        another shape, ``quarters`` has another shape or non-finite labels;
        if ``margin`` is negative, ``gap`` or ``clip`` not positive, or
        ``smooth`` not a positive integer; if a quarter's median flux is not
        positive; if fewer than 10 points are left after masking and
        clipping.

    Examples
    --------
    Two quarters at different flux levels, a 10-d modulation of 0.1 % and
    one outlier:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(0.0, 60.0, 0.02)
    >>> q = np.where(t < 30.0, 1, 2)
    >>> level = np.where(q == 1, 1000.0, 1200.0)
    >>> f = level * (1 + 1e-3 * np.sin(2 * np.pi * t / 10.0) + 1e-4 * rng.normal(size=t.size))
    >>> f[100] *= 1.01
    >>> prep = jp.activity.prepare_light_curve(t, f, quarters=q, mask_transits=False)
    >>> prep.report["points"], prep.report["outliers"], prep.report["n_quarters"]
    (3000, 1, 2)
    >>> print(f"{prep.flux.min():.4f} {prep.flux.max():.4f}")  # both quarters now around 0
    -0.0013 0.0012
    """
    t, f = _series(time, flux)
    if not np.all(np.isfinite(t)):
        raise ValueError("time must be finite")
    margin = _check_positive("margin", margin, strict=False)
    gap = _check_positive("gap", gap)
    clip = _check_positive("clip", clip)
    if not isinstance(smooth, (int, np.integer)) or smooth < 1:
        raise ValueError(f"smooth must be a positive integer number of cadences, got {smooth!r}")
    q, source = _quarter_labels(t, quarters, gap)
    good = np.isfinite(f)
    n_nonfinite = int((~good).sum())
    rel = _relative_flux(f, q, good)
    if system is None and mask_transits:
        from ..model._kepler20 import kepler20_system

        system = kepler20_system()
    keep = good & (transit_mask(t, system, margin) if mask_transits else True)
    n_transit = int((good & ~keep).sum())
    order = np.argsort(t[keep], kind="stable")
    tt, ff, qq = t[keep][order], rel[keep][order], q[keep][order]
    res = ff - _quarter_running_median(ff, qq, smooth)
    sigma = 1.4826 * np.median(np.abs(res - np.median(res)))
    ok = np.abs(res - np.median(res)) <= clip * sigma if sigma > 0 else np.ones(res.size, bool)
    report = {
        "points": int(t.size), "non_finite": n_nonfinite, "in_transit": n_transit,
        "outliers": int((~ok).sum()), "kept": int(ok.sum()), "segments": source,
        "n_quarters": int(np.unique(qq).size), "scatter_ppm": float(sigma * 1e6),
        "rules": (f"transits masked over half duration + {margin} d; outliers > {clip} x 1.4826 MAD "
                  f"from a {smooth}-cadence running median within each quarter"),
    }
    if ok.sum() < 10:
        raise ValueError(f"only {int(ok.sum())} points left after masking and clipping")
    # re-smooth without the outliers so the variability curve is clean
    t_ok, f_ok, q_ok = tt[ok], ff[ok], qq[ok]
    return PreparedLightCurve(t_ok, f_ok, _quarter_running_median(f_ok, q_ok, smooth), q_ok, report)


@dataclasses.dataclass(frozen=True)
class RotationResult:
    """Rotation period from the generalised Lomb-Scargle periodogram.

    Made by ``rotation_period``.

    Attributes
    ----------
    period : float
        The rotation period [d].
    period_err : float
        Its uncertainty [d]: the half width at half maximum of the chosen
        peak, P^2 sigma_f.
    single_peak : float
        Highest peak of the single-sinusoid periodogram [d].
    doubled : bool
        True when the two-harmonic model at about twice ``single_peak`` won
        the BIC test (a two-spot light curve).
    delta_bic : float
        BIC gain of the two-harmonic model (> 0 favours the doubled period;
        -inf when the window around 2 P1 is outside the period range).
    bootstrap : list of float or None
        15.87th, 50th and 84.13th percentiles of the period [d] when whole
        quarters are resampled; None without bootstrap.
    frequency : numpy.ndarray
        Frequency grid [1/d], shape [n_freq].
    power : numpy.ndarray
        Single-sinusoid (``nterms=1``) periodogram, shape [n_freq].
    power2 : numpy.ndarray
        Two-harmonic (``nterms=2``) periodogram, shape [n_freq].
    peaks : list of tuple
        Strongest distinct ``nterms=1`` peaks, (period [d], power), strongest
        first.
    false_alarm : float
        astropy's Baluev false-alarm probability of the single-sinusoid peak
        (white noise assumed; spot evolution makes it far too small to mean
        much).

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.arange(0.0, 120.0, 0.05)
    >>> rot = jp.activity.rotation_period(t, 1e-3 * np.sin(2 * np.pi * t / 12.0))
    >>> print(f"{rot.period:.2f} {rot.single_peak:.2f} {rot.doubled}")
    12.00 12.00 False
    >>> rot.frequency.shape == rot.power.shape == rot.power2.shape
    True
    """

    period: float
    period_err: float
    single_peak: float
    doubled: bool
    delta_bic: float
    bootstrap: list | None
    frequency: np.ndarray
    power: np.ndarray
    power2: np.ndarray
    peaks: list
    false_alarm: float


def _grid(t: np.ndarray, period_min: float, period_max: float, oversample: int) -> np.ndarray:
    span = t.max() - t.min()
    df = 1.0 / (oversample * span)
    return np.arange(1.0 / period_max, 1.0 / period_min + df, df)


def _hwhm(freq: np.ndarray, power: np.ndarray, i: int) -> float:
    """Half width at half maximum [1/d] of the peak at index i (linear
    interpolation of the half-power crossing on each side; the mean of
    the two sides)."""
    half = 0.5 * power[i]
    widths = []
    for step in (-1, 1):
        j = i
        while 0 <= j + step < power.size and power[j + step] > half:
            j += step
        k = j + step
        if not 0 <= k < power.size:
            continue
        # crossing between j (above) and k (below)
        frac = (power[j] - half) / (power[j] - power[k])
        widths.append(abs(freq[j] + frac * (freq[k] - freq[j]) - freq[i]))
    if not widths:
        raise ValueError("the periodogram peak has no half-maximum crossing inside the period range; widen period_min/period_max")
    return float(np.mean(widths))


def _distinct_peaks(freq, power, n, min_sep=0.05):
    """Local maxima, strongest first, at least min_sep (relative) apart in period."""
    loc = np.where((power[1:-1] > power[:-2]) & (power[1:-1] >= power[2:]))[0] + 1
    loc = loc[np.argsort(power[loc])[::-1]]
    out = []
    for j in loc:
        p = 1.0 / freq[j]
        if all(abs(p - q) / q > min_sep for q, _ in out):
            out.append((float(p), float(power[j])))
        if len(out) >= n:
            break
    return out


def _refine(ls, freq, i):
    """Peak frequency on a grid 20x finer than ``freq`` around index i."""
    df = freq[1] - freq[0]
    fine = np.linspace(freq[i] - 2 * df, freq[i] + 2 * df, 81)
    fine = fine[fine > 0]
    return float(fine[np.argmax(ls.power(fine))])


def _choose(t, y, freq, window, bic_threshold, full=True):
    """The period rule (docs/activity.md): the single-sinusoid GLS peak P1,
    unless the two-harmonic GLS peak within +-``window`` (relative) of 2 P1
    lowers the BIC by more than ``bic_threshold`` (two extra parameters)."""
    from astropy.timeseries import LombScargle

    ls1 = LombScargle(t, y)  # floating mean (fit_mean=True) is the default
    p1 = ls1.power(freq)
    i1 = int(np.argmax(p1))
    f1 = freq[i1]
    ls2 = LombScargle(t, y, nterms=2)
    win = (freq > 0.5 * f1 / (1 + window)) & (freq < 0.5 * f1 / (1 - window))
    if full:
        p2 = ls2.power(freq)
    else:
        p2 = np.full(freq.shape, np.nan)
        if win.any():
            p2[win] = ls2.power(freq[win])
    delta_bic = -np.inf
    if win.any():
        i2 = int(np.flatnonzero(win)[np.argmax(p2[win])])
        # standard normalisation: power = 1 - chi2 / chi2_ref, so the
        # chi2 ratio of the two models is (1 - p1) / (1 - p2)
        n = t.size
        delta_bic = n * np.log((1 - p1[i1]) / (1 - p2[i2])) - 2 * np.log(n)
    if delta_bic > bic_threshold:
        return ls2, i2, p1, p2, True, float(delta_bic), ls1, i1
    return ls1, i1, p1, p2, False, float(delta_bic), ls1, i1


def rotation_period(time, flux, period_min: float = 2.0, period_max: float = 45.0, oversample: int = 10,
                    harmonic_window: float = 0.1, bic_threshold: float = 10.0, quarters=None,
                    bootstrap: int = 0, seed: int = 0, n_peaks: int = 6) -> RotationResult:
    """Measure the rotation period with astropy's generalised (floating-mean) Lomb-Scargle.

    The single-sinusoid peak P1 is the period unless the light curve has the
    shape of two spot groups (most power at P_rot / 2): then a
    two-harmonic model (astropy ``nterms=2``) at about 2 P1 fits better by
    more than ``bic_threshold`` in BIC (10: "very strong", Kass & Raftery
    1995) and its peak is taken. A two-harmonic periodogram alone would not
    do: it has the same power at 2P as at P for a pure sinusoid
    (Zechmeister & Kuerster 2009; Mueller et al. 2021, Sect. 3.2).

    Parameters
    ----------
    time : array_like
        Times [d], shape [n_times], finite, at least 10 points.
    flux : array_like
        Relative flux (e.g. ``PreparedLightCurve.flux``), shape [n_times],
        finite.
    period_min : float, optional
        Lower end of the search range [d] (default 2).
    period_max : float, optional
        Upper end of the search range [d] (default 45, half a Kepler quarter:
        each quarter is normalised separately and PDC removes slower trends,
        so longer periods are not measurable). At most the time span.
    oversample : int, optional
        Frequency steps per 1/(time span), >= 3 (default 10).
    harmonic_window : float, optional
        Relative half width of the window around 2 P1, in (0, 0.5)
        (default 0.1).
    bic_threshold : float, optional
        BIC gain needed to take the doubled period (default 10).
    quarters : array_like, optional
        Labels for the bootstrap (whole quarters are resampled), shape
        [n_times]; needed when ``bootstrap`` > 0.
    bootstrap : int, optional
        Number of quarter-bootstrap draws (default 0: none).
    seed : int, optional
        Seed of the bootstrap's random generator (default 0).
    n_peaks : int, optional
        Number of distinct peaks listed in ``RotationResult.peaks``
        (default 6).

    Returns
    -------
    RotationResult
        The period, its error, the periodograms and the peaks.
        ``period_err`` is the HWHM of the peak: the frequency resolution of
        the data. A strictly periodic signal is located much better than
        that; an evolving spot pattern is not (see the bootstrap).

    Raises
    ------
    ValueError
        If ``time`` is not 1D with at least 10 points, ``flux`` has another
        shape, or either is not finite; if ``period_min`` or ``period_max``
        is not positive, ``period_max <= period_min`` or ``period_max``
        exceeds the time span; if ``oversample`` is not an integer >= 3,
        ``harmonic_window`` is outside (0, 0.5), ``bic_threshold`` is not
        finite, ``bootstrap`` is not a non-negative integer; if a bootstrap
        is asked for without ``quarters`` or with ``quarters`` of another
        shape; if the peak has no half-maximum crossing inside the range.

    Examples
    --------
    A sinusoid of period 12 d, and a two-spot light curve whose strongest
    single-sinusoid peak is at half the rotation period:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(0.0, 120.0, 0.05)
    >>> noise = 1e-4 * rng.normal(size=t.size)
    >>> rot = jp.activity.rotation_period(t, 1e-3 * np.sin(2 * np.pi * t / 12.0) + noise)
    >>> print(f"P = {rot.period:.2f} +- {rot.period_err:.2f} d, doubled: {rot.doubled}")
    P = 12.00 +- 0.53 d, doubled: False
    >>> two = 3e-4 * np.sin(2 * np.pi * t / 12.0) + 1e-3 * np.sin(4 * np.pi * t / 12.0 + 1.0)
    >>> rot = jp.activity.rotation_period(t, two + noise)
    >>> print(f"P1 = {rot.single_peak:.2f} d -> P = {rot.period:.2f} d, doubled: {rot.doubled}")
    P1 = 6.00 d -> P = 12.00 d, doubled: True
    """
    t, y = _series(time, flux)
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("time and flux must be finite (use prepare_light_curve first)")
    period_min = _check_positive("period_min", period_min)
    period_max = _check_positive("period_max", period_max)
    if period_max <= period_min:
        raise ValueError(f"period_max must exceed period_min, got {period_max} <= {period_min}")
    span = t.max() - t.min()
    if period_max > span:
        raise ValueError(f"period_max = {period_max} d exceeds the time span {span:.3g} d")
    if not isinstance(oversample, (int, np.integer)) or oversample < 3:
        raise ValueError(f"oversample must be an integer >= 3, got {oversample!r}")
    if not (0 < harmonic_window < 0.5):
        raise ValueError(f"harmonic_window must be in (0, 0.5), got {harmonic_window!r}")
    bic_threshold = float(bic_threshold)
    if not np.isfinite(bic_threshold):
        raise ValueError(f"bic_threshold must be finite, got {bic_threshold!r}")
    if not isinstance(bootstrap, (int, np.integer)) or bootstrap < 0:
        raise ValueError(f"bootstrap must be a non-negative integer, got {bootstrap!r}")
    if bootstrap and quarters is None:
        raise ValueError("bootstrap needs quarters (labels of the resampled blocks)")
    freq = _grid(t, period_min, period_max, oversample)
    ls, i, p1, p2, doubled, dbic, ls1, i1 = _choose(t, y, freq, harmonic_window, bic_threshold)
    power = p2 if doubled else p1
    period = 1.0 / _refine(ls, freq, i)
    period_err = period**2 * _hwhm(freq, power, i)
    fap = float(ls1.false_alarm_probability(p1[i1], minimum_frequency=freq[0], maximum_frequency=freq[-1]))
    boot = None
    if bootstrap:
        q = np.asarray(quarters, float)
        if q.shape != t.shape:
            raise ValueError(f"quarters must have the shape of time {t.shape}, got {q.shape}")
        labels = np.unique(q)
        rng = np.random.default_rng(seed)
        draws = []
        for _ in range(bootstrap):
            pick = rng.choice(labels, labels.size, replace=True)
            # a quarter drawn twice keeps its own times: its spot pattern then
            # counts twice, which is what block resampling means here
            idx = np.concatenate([np.flatnonzero(q == lab) for lab in pick])
            _, j, *_ = _choose(t[idx], y[idx], freq, harmonic_window, bic_threshold, full=False)
            draws.append(1.0 / freq[j])
        boot = [float(v) for v in np.percentile(draws, [15.87, 50.0, 84.13])]
    return RotationResult(float(period), float(period_err), float(1.0 / _refine(ls1, freq, i1)), bool(doubled),
                          dbic, boot, freq, p1, p2, _distinct_peaks(freq, p1, n_peaks), fap)


def quarter_variability(prepared: PreparedLightCurve, lower: float = 1.0, upper: float = 99.0) -> dict:
    """Peak-to-peak variability per quarter [%].

    The ``lower``-``upper`` percentile range of the running-median curve
    ``prepared.smooth`` in each quarter (robust to outliers and to the white
    noise, which the running median averages down). Mueller et al. (2021),
    Sect. 3.2, find 0.1-0.2 % for Kepler-20, at most 0.6 % (quarter 17).

    Parameters
    ----------
    prepared : PreparedLightCurve
        The light curve from ``prepare_light_curve``.
    lower : float, optional
        Lower percentile (default 1).
    upper : float, optional
        Upper percentile (default 99).

    Returns
    -------
    dict
        {quarter label (str, e.g. ``"17"``): peak-to-peak variability [%]}.

    Raises
    ------
    ValueError
        Unless 0 <= ``lower`` < ``upper`` <= 100.

    Examples
    --------
    A 0.1 % sinusoid (peak-to-peak 0.2 %, of which the 1st-99th percentile
    range covers 0.199 %) in the first quarter, half of it in the second:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> t = np.arange(0.0, 60.0, 0.02)
    >>> q = np.where(t < 30.0, 1, 2)
    >>> amp = np.where(q == 1, 1e-3, 5e-4)
    >>> prep = jp.activity.prepare_light_curve(t, 1 + amp * np.sin(2 * np.pi * t / 10.0), quarters=q,
    ...                                        mask_transits=False)
    >>> var = jp.activity.quarter_variability(prep)
    >>> print({k: round(v, 3) for k, v in var.items()})
    {'1': 0.199, '2': 0.1}
    """
    if not 0 <= lower < upper <= 100:
        raise ValueError(f"lower, upper must satisfy 0 <= lower < upper <= 100, got {lower}, {upper}")
    out = {}
    for qv in np.unique(prepared.quarter):
        s = prepared.smooth[prepared.quarter == qv]
        key = str(int(qv)) if float(qv).is_integer() else f"{qv:g}"
        out[key] = float(100.0 * (np.percentile(s, upper) - np.percentile(s, lower)))
    return out
