"""``activity_report``: the whole activity analysis of a light curve, as a
JSON-serialisable dict, with figures (what ``jaxppo activity`` runs)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..model._processes import on_writer
from ..model._strict_json import strict_jsonable
from ._map import brightness_map, plot_brightness_map, plot_periodogram, plot_spot_fit
from ._spots import KEPLER20_SPOT_CONTRAST, fit_spots
from ._rotation import (PAPER_ROTATION_PERIOD, PAPER_ROTATION_PERIOD_ERR, prepare_light_curve,
                        quarter_variability, rotation_period)

__all__ = ["activity_report", "report_lines"]

# Mueller et al. (2021), Sect. 3.2: peak-to-peak 0.1-0.2 %, largest 0.6 % in Q17.
PAPER_VARIABILITY = {"typical_percent": [0.1, 0.2], "largest_percent": 0.6, "largest_quarter": "17"}


def _rotation_report(prep, rot, var, bmap, bootstrap, period_min, period_max, bins) -> dict:
    """The report's rotation, variability and map entries."""
    return {
        "n_points": prep.report["points"],
        "preparation": prep.report,
        "rotation": {
            "period_d": rot.period,
            "period_err_d": rot.period_err,
            "period_err_method": "half width at half maximum of the GLS peak, P^2 * HWHM_f",
            "bootstrap_percentiles_16_50_84_d": rot.bootstrap,
            "bootstrap_draws": bootstrap if rot.bootstrap is not None else 0,
            "single_sinusoid_peak_d": rot.single_peak,
            "doubled": rot.doubled,
            "delta_bic_doubled": rot.delta_bic,
            "rule": "single-sinusoid GLS peak P1, or the two-harmonic (nterms=2) peak within 10 % of 2 P1 if it lowers the BIC by > 10",
            # the BIC counts every cadence as independent; evolving spots leave
            # correlated residuals, and a gain of ~100 then also doubles
            # single-spot light curves (a review: 3 of 16 simulated, P = 9 and 18 d)
            "caution": (f"the doubling from P1 = {rot.single_peak:.2f} d rests on a BIC gain of {rot.delta_bic:.0f}, "
                        "which counts every cadence as independent: evolving spots' correlated residuals give such "
                        "gains to single-spot light curves too, so P1 is not excluded" if rot.doubled else None),
            "false_alarm_probability": rot.false_alarm,
            "peaks": [{"period_d": p, "power": w} for p, w in rot.peaks],
            "period_range_d": [period_min, period_max],
            "periodogram": "astropy.timeseries.LombScargle (generalised, floating mean)",
        },
        "variability_percent": var,
        "variability_method": "1st-99th percentile of a 25-cadence running median, per quarter",
        "map": {"period_d": bmap.period, "t_ref": bmap.t_ref, "n_chunks": int(bmap.chunk_start.size),
                "bins_per_rotation": bins, "repeated_fraction": 0.5},
    }


def _spot_report(prep, bmap, spot_chunk, n_spots, spot_contrast):
    """Invert the map chunk(s) ``spot_chunk`` with ``n_spots`` spots:
    (spots for the map, the first chunk's SpotFit, its points, the report's
    "spots" entry)."""
    spots, spot_fit, chunk_sel = None, None, None
    n_chunk = int(bmap.chunk_start.size)
    if isinstance(spot_chunk, str) and spot_chunk == "all":
        # chunks with at least 60 % of their phase bins filled
        own = bmap.counts[:, ~bmap.repeated] >= 3
        chunks = [k for k in range(n_chunk) if own[k].mean() >= 0.6]
    elif isinstance(spot_chunk, (int, np.integer)) and not isinstance(spot_chunk, bool) and 0 <= spot_chunk < n_chunk:
        chunks = [int(spot_chunk)]
    else:
        raise ValueError(f"spot_chunk must be a chunk index in 0..{n_chunk - 1} or 'all', got {spot_chunk!r}")
    spots, fits = [], []
    for k in chunks:
        start = float(bmap.chunk_start[k])
        sel = (prep.time >= start) & (prep.time < start + bmap.period)
        if sel.sum() < 50:
            raise ValueError(f"spot_chunk {k} holds only {int(sel.sum())} points; pick another")
        fit = fit_spots(prep.time[sel], prep.flux[sel], bmap.period, n_spots=n_spots,
                        contrast=spot_contrast, t_ref=bmap.t_ref)
        if spot_fit is None:
            spot_fit, chunk_sel = fit, sel
        spots += [(start + 0.5 * bmap.period, lon / 360.0, rad) for lon, rad in zip(fit.lon, fit.radius)]
        fits.append({
            "chunk": int(k), "chunk_start": start, "n_points": int(sel.sum()),
            "longitude_deg": fit.lon.tolist(), "latitude_deg": fit.lat.tolist(),
            "radius_deg": fit.radius.tolist(), "unspotted_level": fit.offset,
            "chi2": fit.chi2, "sigma": fit.sigma, "success": fit.success,
        })
    entry = {
        "contrast": float(spot_contrast), "inclination_deg": 90.0, "latitude_deg": 0.0, "n_spots": int(n_spots),
        "phase_of_longitude": "a spot crosses the central meridian at map phase longitude / 360",
        "note": ("small-spot model, contrast and latitude fixed, star equator-on: radii are lower limits "
                 "(contrast, latitude and size are degenerate)"),
        "chunks": fits,
    }
    return spots, spot_fit, chunk_sel, entry


def _write(report, out, prep, rot, var, bmap, spots, spot_fit, chunk_sel, compare_paper) -> None:
    """activity.json and the figures ``report["figures"]`` in ``out`` (created)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plot_periodogram(prep, rot, var, out / "activity_periodogram.png", PAPER_ROTATION_PERIOD if compare_paper else None)
    plot_brightness_map(bmap, out / "activity_map.png", spots=spots)
    if spot_fit is not None:
        plot_spot_fit(prep.time[chunk_sel], prep.flux[chunk_sel], spot_fit, out / "activity_spots.png")
    with open(out / "activity.json", "w") as fh:
        json.dump(report, fh, indent=2, allow_nan=False)


def activity_report(time, flux, out=None, system=None, quarters=None, period_min: float = 2.0,
                    period_max: float = 45.0, bootstrap: int = 50, seed: int = 0,
                    bins: int = 50, mask_transits: bool = True, margin: float = 0.1,
                    compare_paper: bool = True, spot_chunk: int | str | None = None, n_spots: int = 3,
                    spot_contrast: float = KEPLER20_SPOT_CONTRAST) -> dict:
    """Run the whole activity analysis of a light curve: rotation period, variability, brightness map.

    What ``jaxppo activity`` runs (Mueller et al. 2021, Sects. 2.4 and
    3.2): ``prepare_light_curve``, ``rotation_period`` (with a
    quarter bootstrap when there is more than one quarter),
    ``quarter_variability``, ``brightness_map`` at the period found
    and, optionally, ``fit_spots`` on map chunks.

    Parameters
    ----------
    time : array_like
        Times [d], shape [n_times].
    flux : array_like
        Fluxes (any positive unit), shape [n_times].
    out : str or os.PathLike, optional
        Directory (created) for activity.json, activity_periodogram.png,
        activity_map.png and, with a spot inversion, activity_spots.png;
        None (default) writes nothing.
    system : jaxppo.System, optional
        The system whose transits are masked; None (default): Kepler-20 b
        and c.
    quarters : array_like, optional
        Quarter label per point, shape [n_times]; None (default): segments
        split at gaps > 0.5 d.
    period_min : float, optional
        Shortest period of the periodogram search [d] (default 2; see
        ``rotation_period``).
    period_max : float, optional
        Longest period of the periodogram search [d] (default 45).
    bootstrap : int, optional
        Quarter-bootstrap draws for the period spread (default 50; 0: none).
    seed : int, optional
        Seed of the bootstrap (default 0).
    bins : int, optional
        Phase bins per rotation in the map (default 50).
    mask_transits : bool, optional
        False keeps the transits in (default True).
    margin : float, optional
        Added to each half transit duration [d] in the mask (default 0.1).
    compare_paper : bool, optional
        Include Mueller et al. (2021)'s Kepler-20 numbers (period 26.948 d,
        variability 0.1-0.2 %, 0.6 % in Q17) and the difference to them
        (default True).
    spot_chunk : int or str, optional
        Index of the map chunk to invert with ``n_spots`` equatorial spots of
        contrast ``spot_contrast`` (``fit_spots``), or ``"all"`` (every
        chunk with >= 60 % phase coverage); the spots are drawn on the map,
        the first fitted chunk in activity_spots.png. None (default): no
        inversion.
    n_spots : int, optional
        Spots per inverted chunk (default 3).
    spot_contrast : float, optional
        Spot contrast 1 - I_spot / I_phot (default 0.59).

    Returns
    -------
    dict
        Strict JSON (only finite numbers, strings, lists and dicts; NaN
        becomes None): ``n_points``, ``preparation`` (the
        ``PreparedLightCurve`` report), ``rotation`` (period and errors
        [d], the rule, peaks, false-alarm probability), ``variability_percent``
        per quarter, ``map``, and ``paper``, ``spots`` and ``figures`` when
        asked for.

    Raises
    ------
    ValueError
        If ``compare_paper`` is not a bool; if ``spot_chunk`` is neither a
        chunk index nor ``"all"``, or a chosen chunk holds fewer than 50
        points; and whatever ``prepare_light_curve``,
        ``rotation_period`` and ``brightness_map`` refuse.

    Examples
    --------
    >>> import os
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> rng = np.random.default_rng(2)
    >>> t = np.arange(0.0, 90.0, 0.05)
    >>> q = np.where(t < 45.0, 1, 2)
    >>> f = 1000.0 * (1 + 1e-3 * np.sin(2 * np.pi * t / 12.0) + 1e-4 * rng.normal(size=t.size))
    >>> rep = jp.activity.activity_report(t, f, out="activity", quarters=q, mask_transits=False,
    ...                                   bootstrap=0, compare_paper=False)
    >>> print(f"P = {rep['rotation']['period_d']:.2f} +- {rep['rotation']['period_err_d']:.2f} d")
    P = 12.00 +- 0.71 d
    >>> print({k: round(v, 2) for k, v in rep["variability_percent"].items()}, rep["map"]["n_chunks"])
    {'1': 0.2, '2': 0.2} 8
    >>> sorted(os.listdir("activity"))
    ['activity.json', 'activity_map.png', 'activity_periodogram.png']
    """
    if not isinstance(compare_paper, bool):
        raise ValueError(f"compare_paper must be True or False, got {compare_paper!r}")
    prep = prepare_light_curve(time, flux, quarters=quarters, system=system,
                               mask_transits=mask_transits, margin=margin)
    n_quarters = np.unique(prep.quarter).size
    rot = rotation_period(prep.time, prep.flux, period_min=period_min, period_max=period_max,
                          quarters=prep.quarter,
                          bootstrap=bootstrap if n_quarters > 1 else 0, seed=seed)
    var = quarter_variability(prep)
    bmap = brightness_map(prep.time, prep.flux, rot.period, bins=bins)
    report = _rotation_report(prep, rot, var, bmap, bootstrap, period_min, period_max, bins)
    if compare_paper:
        report["paper"] = {
            "rotation_period_d": PAPER_ROTATION_PERIOD, "rotation_period_err_d": PAPER_ROTATION_PERIOD_ERR,
            **PAPER_VARIABILITY,
            "period_difference_d": rot.period - PAPER_ROTATION_PERIOD,
            "period_difference_in_hwhm": (rot.period - PAPER_ROTATION_PERIOD) / rot.period_err,
            "source": "Mueller, Ioannidis & Schmitt (2021), Sect. 3.2",
        }
    spots, spot_fit, chunk_sel = None, None, None
    if spot_chunk is not None:
        spots, spot_fit, chunk_sel, report["spots"] = _spot_report(prep, bmap, spot_chunk, n_spots, spot_contrast)
    report = strict_jsonable(report)
    if out is not None:  # process 0 (of several JAX processes) writes
        report["figures"] = ["activity_periodogram.png", "activity_map.png"] + ["activity_spots.png"] * (spot_fit is not None)
        on_writer(f"writing the activity report into {out}",
                  lambda: _write(report, out, prep, rot, var, bmap, spots, spot_fit, chunk_sel, compare_paper))
    return report


def report_lines(rep: dict, kepler20_mask: bool = False) -> list[str]:
    """What ``jaxppo activity`` prints of an ``activity_report``: with
    ``kepler20_mask`` (a file of the user's, masked by Kepler-20 b-f's
    bundled ephemerides whatever star it holds) how many points the mask
    took, then the rotation period, its caution and bootstrap, the
    variability per quarter and the paper's period."""
    rot, prep, lines = rep["rotation"], rep.get("preparation") or {}, []
    if kepler20_mask:
        lines.append(f"masked the transits of Kepler-20 b-f (the bundled ephemerides): {prep.get('in_transit')} of "
                     f"{prep.get('points')} points (--no-transit-mask keeps them: for a star other than Kepler-20)")
    lines.append(f"rotation period {rot['period_d']:.3f} +- {rot['period_err_d']:.3f} d ({rot['period_err_method']})")
    if rot.get("caution"):
        lines.append(f"  caution: {rot['caution']}")
    if rot.get("bootstrap_percentiles_16_50_84_d"):
        lo, med, hi = rot["bootstrap_percentiles_16_50_84_d"]
        lines.append(f"quarter bootstrap 16/50/84 %: {lo:.2f} / {med:.2f} / {hi:.2f} d")
    var = rep["variability_percent"]
    if isinstance(var, dict):
        lines.append("peak-to-peak variability per quarter [%]: " + ", ".join(
            f"{k} {v:.2f}" for k, v in var.items() if isinstance(v, (int, float))))
    if "paper" in rep:
        lines.append(f"paper (Mueller et al. 2021, Kepler-20): {rep['paper']['rotation_period_d']} +- "
                     f"{rep['paper']['rotation_period_err_d']} d")
    return lines
