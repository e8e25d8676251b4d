"""The multi-transit windows the obliquity scan's chi^2 sees (paper
Sect. 2.2): the events of the tilted planet that have data, each window
divided by its out-of-transit polynomial, outliers of the baseline dropped,
the errors estimated from the baseline scatter when the data have none."""

from __future__ import annotations

import dataclasses

import numpy as np

from ._config import ScanConfig, require_scan_system
from ..model._lightcurve import LightCurve
from ..model._overlap import in_transit_mask
from ..model._transits import MultiTransit, multi_transits

__all__ = ["ScanWindow", "scan_windows", "windows_and_events", "scan_events", "robust_sigma", "windows_lightcurve", "windows_data"]

# Extra width [d] (15 min) of each transit window in the out-of-transit mask:
# room for ephemeris errors, so no ingress point bends the baseline.
_TRANSIT_PAD = 15.0 / 1440.0
# [scan] multi_transits lists mid-times; an event matches within this [d]
_EVENT_MATCH = 0.1


@dataclasses.dataclass(frozen=True)
class ScanWindow:
    """One multi-transit as the scan's chi^2 sees it (immutable).

    Made by ``jaxppo.scan_windows``; a finished scan keeps its windows in
    ``ScanResult.windows``.

    Attributes
    ----------
    number : int
        1-based, as in ``summary["multi_transits"]`` and the scan's figures.
    event : MultiTransit
        The multi-transit (start, end and mid-time [d], the planets).
    time : numpy.ndarray
        Times [d] of the points inside [event.start - margin, event.end +
        margin] kept after outlier removal, [n_points].
    flux : numpy.ndarray
        Their flux divided by the window's out-of-transit polynomial,
        [n_points].
    flux_err : numpy.ndarray
        Their errors, [n_points]: the data's errors divided by the trend,
        or ``sigma`` where estimated (as loaded without detrending).
    exposure : float or None
        Exposure time [d] of each point; None: instantaneous.
    baseline_points : int
        Out-of-transit points the trend was fitted to (0 without detrending).
    clipped : int
        Points dropped as outliers (out of transit only).
    sigma : float or None
        The error estimated from the out-of-transit scatter; None when the
        data's own errors are used.
    trend : tuple of float
        Polynomial coefficients (highest power first) in t - event.mid [d];
        empty without detrending.

    Examples
    --------
    >>> import jaxppo as jp
    >>> cfg = jp.load_config()  # the bundled real Kepler-20 data, detrended
    >>> w = jp.scan_windows(cfg)[0]
    >>> print(w.number, w.event.planets, f"{w.event.mid:.2f}", w.time.size)
    1 ('b', 'c') 334.02 17
    >>> len(w.trend), w.baseline_points, w.clipped  # a quadratic trend
    (3, 27, 0)
    >>> w.as_dict()["points"]
    17
    """

    number: int
    event: MultiTransit
    time: np.ndarray
    flux: np.ndarray
    flux_err: np.ndarray
    exposure: float | None
    baseline_points: int = 0
    clipped: int = 0
    sigma: float | None = None
    trend: tuple = ()

    def as_dict(self) -> dict:
        """The window as an entry of ``summary["multi_transits"]``.

        Returns
        -------
        dict
            The event's fields (``MultiTransit.as_dict``: start, end,
            mid [d], planets, ...) with ``number``, ``points``,
            ``baseline_points``, ``clipped`` and ``sigma``.
        """
        return dict(self.event.as_dict(), number=self.number, points=int(self.time.size),
                    baseline_points=self.baseline_points, clipped=self.clipped, sigma=self.sigma)



def robust_sigma(r: np.ndarray) -> float:
    """1.4826 x the median absolute deviation: the Gaussian sigma, unmoved by
    a few outliers."""
    return float(1.4826 * np.median(np.abs(r - np.median(r))))



def _detrend_window(t, f, e, oot, mid, order, clip, estimate):
    """Fit the polynomial to the out-of-transit points, iteratively dropping
    those whose residual exceeds ``clip`` robust sigmas (never in-transit
    points: a PPO bump or a transit cannot be clipped). Returns the kept mask,
    the trend coefficients and the estimated sigma (or None)."""
    keep = np.ones(t.size, bool)
    x = t - mid
    w = None if estimate else 1.0 / e
    for _ in range(10):
        fit_pts = oot & keep
        coef = np.polyfit(x[fit_pts], f[fit_pts], order, w=None if w is None else w[fit_pts])
        res = f / np.polyval(coef, x) - 1.0
        if clip is None:
            break
        s_rob = robust_sigma(res[fit_pts])
        if not s_rob > 0:  # noise-free data: nothing is an outlier
            break
        new = keep & ~(oot & (np.abs(res) > clip * s_rob))
        # stop when nothing changes, or before the baseline gets too thin
        if new.sum() == keep.sum() or (oot & new).sum() < order + 3:
            break
        keep = new
    fit_pts = oot & keep
    sigma = None
    if estimate:
        # unbiased residual variance of the kept baseline (n - order - 1 dof)
        r = f[fit_pts] / np.polyval(coef, x[fit_pts]) - 1.0
        sigma = float(np.sqrt(np.sum(r**2) / (fit_pts.sum() - order - 1)))
    return keep, coef, sigma


def scan_windows(cfg: ScanConfig) -> list[ScanWindow]:
    """Cut, detrend and clean the multi-transit windows the scan's chi^2 uses.

    The multi-transits of the tilted planet that have data, each with the
    detrended, outlier-cleaned points the chi^2 uses (paper Sect. 2.2).

    Per event: the baseline is [start - baseline, end + baseline]; its points
    outside every planet's transit (contact times, widened by half an
    exposure + 15 min) fit a polynomial of order ``detrend``, and the window
    is divided by it. Outliers: baseline points more than ``clip`` x 1.4826
    MAD from the trend are dropped (iterated); in-transit points are never
    clipped. When the data carry no errors (``lightcurve.errors_estimated``),
    each window's error is the rms of its baseline residuals with
    n - order - 1 degrees of freedom. Events with too few baseline points
    (fewer than order + 3 in all or fewer than 2 on a side) are skipped and
    listed in ``skipped_multi_transits`` of the scan's summary.
    ``detrend = "none"``: the flux is used as loaded.

    Parameters
    ----------
    cfg : ScanConfig
        The configuration (``load_config``): system, data, ``margin``,
        ``baseline``, ``detrend``, ``clip`` and ``events``.

    Returns
    -------
    list of ScanWindow
        One window per usable multi-transit, numbered from 1 in time order.

    Raises
    ------
    ValueError
        When a mid-time of ``cfg.events`` ([scan] multi_transits) matches no
        multi-transit, or when the data hold no usable multi-transit of the
        tilted planet.

    Examples
    --------
    >>> import jaxppo as jp
    >>> windows = jp.scan_windows(jp.load_config())  # real Kepler-20 data
    >>> len(windows)
    8
    >>> [round(w.event.mid, 2) for w in windows[:3]]
    [334.02, 496.77, 670.46]
    >>> [w.time.size for w in windows[:3]]
    [17, 15, 12]
    """
    return windows_and_events(cfg)[0]


def windows_and_events(cfg: ScanConfig):
    """(windows, skipped) of a scan config: the detrended data window of
    every multi-transit of the tilted planet that has data, and the events
    left out with the reason."""
    require_scan_system(cfg.system, "the scan's multi-transit windows (jaxppo scan; fit and sample --windows)")
    sysm, lc = cfg.system, cfg.lightcurve
    tilted_name = sysm.planets[sysm.tilted].name
    tilted_label = tilted_name or str(sysm.tilted)
    events = [e for e in multi_transits(sysm, float(lc.time.min()) - 1.0, float(lc.time.max()) + 1.0)
              if tilted_label in e.planets]
    if cfg.events is not None:
        # only the listed multi-transits (e.g. the paper's seven)
        missing = [m for m in cfg.events if not any(abs(e.mid - m) < _EVENT_MATCH for e in events)]
        if missing:
            raise ValueError(f"{cfg.source}: [scan] multi_transits: no multi-transit of planet {tilted_label!r} "
                             f"within {_EVENT_MATCH} d of {missing}; the data hold {[round(e.mid, 2) for e in events]}")
        events = [e for e in events if any(abs(e.mid - m) < _EVENT_MATCH for m in cfg.events)]
    order, clip = cfg.detrend, cfg.clip
    pad = 0.5 * (lc.exposure or 0.0) + _TRANSIT_PAD
    windows, skipped = [], []
    for e in events:
        lo, hi = e.start - cfg.margin, e.end + cfg.margin
        if order is None:
            sel = (lc.time >= lo) & (lc.time <= hi)
            if sel.any():
                windows.append(ScanWindow(len(windows) + 1, e, lc.time[sel], lc.flux[sel], lc.flux_err[sel], lc.exposure))
            continue
        base = (lc.time >= e.start - cfg.baseline) & (lc.time <= e.end + cfg.baseline)
        chi_sel = (lc.time[base] >= lo) & (lc.time[base] <= hi)
        if not chi_sel.any():
            continue
        t, f, err = lc.time[base], lc.flux[base], lc.flux_err[base]
        oot = ~in_transit_mask(sysm, t, pad)
        n_left, n_right = int((oot & (t < e.start)).sum()), int((oot & (t > e.end)).sum())
        if oot.sum() < order + 3 or (order >= 1 and min(n_left, n_right) < 2):
            skipped.append({"mid": e.mid, "reason": f"{int(oot.sum())} out-of-transit baseline points "
                            f"({n_left} before, {n_right} after); need >= {order + 3} and >= 2 on each side"})
            continue
        keep, coef, sigma = _detrend_window(t, f, err, oot, e.mid, order, clip, lc.errors_estimated)
        trend = np.polyval(coef, t - e.mid)
        use = chi_sel & keep
        fe = np.full(t.size, sigma) if sigma is not None else err / trend
        windows.append(ScanWindow(
            len(windows) + 1, e, t[use], f[use] / trend[use], fe[use], lc.exposure,
            baseline_points=int((oot & keep).sum()), clipped=int((~keep).sum()), sigma=sigma,
            trend=tuple(float(c) for c in coef)))
    if not windows:
        raise ValueError(
            f"{cfg.source}: the data ({lc.time.min():.3f} .. {lc.time.max():.3f}) contain no usable multi-transit "
            f"of planet {tilted_label!r}" + (f" (skipped: {skipped})" if skipped else "")
        )
    return windows, skipped


def scan_events(cfg: ScanConfig):
    """(event, mask of ``cfg.lightcurve``) of the multi-transits the scan
    uses, numbered as ``scan_windows`` (the mask covers the chi^2 window
    of the raw light curve; the detrended points are in scan_windows)."""
    lc = cfg.lightcurve
    return [(w.event, (lc.time >= w.event.start - cfg.margin) & (lc.time <= w.event.end + cfg.margin))
            for w in scan_windows(cfg)]


def windows_lightcurve(cfg: ScanConfig) -> LightCurve:
    """The points of every window of ``scan_windows`` as one
    ``LightCurve`` (detrended, outlier-cleaned; a point shared by the
    windows of neighbouring events kept once): the data as the scan sees
    them, e.g. for fitting real data with stellar variability."""
    wins = scan_windows(cfg)
    said = {k: v for k, v in cfg.lightcurve.report.items() if k == "exposure_note"}  # warned once, at loading
    lc = windows_data(wins, cfg.lightcurve.exposure,
                      report={"windows": f"{len(wins)} detrended multi-transit windows of {cfg.source}", **said})
    return dataclasses.replace(lc, instantaneous=cfg.lightcurve.instantaneous)


def windows_data(windows, exposure, report=None) -> LightCurve:
    """The points of ``windows`` as one ``LightCurve``, a point shared by
    the windows of neighbouring events (a chain of events through one
    transit of the tilted planet) kept once, as its first window has it:
    the chi^2 counts each point once (the scan crashed on the repeated
    time stamps)."""
    t = np.concatenate([w.time for w in windows])
    f = np.concatenate([w.flux for w in windows])
    e = np.concatenate([w.flux_err for w in windows])
    _, first = np.unique(t, return_index=True)
    return LightCurve(t[first], f[first], e[first], exposure=exposure, report=report or {})
