"""``activity_report``: the whole activity analysis of a light curve, as a
JSON-serialisable dict, with figures (what ``jaxppo activity`` runs)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ._map import brightness_map, plot_brightness_map, plot_periodogram
from ._rotation import (PAPER_ROTATION_PERIOD, PAPER_ROTATION_PERIOD_ERR, prepare_light_curve,
                        quarter_variability, rotation_period)

__all__ = ["activity_report"]

# Mueller et al. (2021), Sect. 3.2: peak-to-peak 0.1-0.2 %, largest 0.6 % in Q17.
PAPER_VARIABILITY = {"typical_percent": [0.1, 0.2], "largest_percent": 0.6, "largest_quarter": "17"}


def _clean(x):
    """Strict JSON: floats must be finite (NaN/Infinity become None)."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    return x


def activity_report(time, flux, out=None, system=None, quarters=None, period_min: float = 2.0,
                    period_max: float = 45.0, bootstrap: int = 50, seed: int = 0,
                    bins: int = 50, mask_transits: bool = True, margin: float = 0.1,
                    compare_paper: bool = True) -> dict:
    """Rotation period, per-quarter variability and brightness map.

    Args:
        time [d], flux (any positive unit): the light curve, 1D.
        out: directory for activity.json, activity_periodogram.png and
            activity_map.png (created); None writes nothing.
        system: jaxppo.System whose transits are masked (default Kepler-20 b, c).
        quarters: quarter label per point; None: segments split at gaps > 0.5 d.
        period_min, period_max [d]: periodogram search range (see rotation_period).
        bootstrap: quarter-bootstrap draws for the period spread (0: none).
        bins: phase bins per rotation in the map.
        compare_paper: include Mueller et al. (2021)'s Kepler-20 numbers.
    Returns a dict with only finite numbers, strings, lists and dicts.
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
    report = {
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
    if compare_paper:
        report["paper"] = {
            "rotation_period_d": PAPER_ROTATION_PERIOD, "rotation_period_err_d": PAPER_ROTATION_PERIOD_ERR,
            **PAPER_VARIABILITY,
            "period_difference_d": rot.period - PAPER_ROTATION_PERIOD,
            "period_difference_in_hwhm": (rot.period - PAPER_ROTATION_PERIOD) / rot.period_err,
            "source": "Mueller, Ioannidis & Schmitt (2021), Sect. 3.2",
        }
    report = _clean(report)
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        fig_p = plot_periodogram(prep, rot, var, out / "activity_periodogram.png",
                                 PAPER_ROTATION_PERIOD if compare_paper else None)
        fig_m = plot_brightness_map(bmap, out / "activity_map.png")
        report["figures"] = [Path(fig_p).name, Path(fig_m).name]
        with open(out / "activity.json", "w") as fh:
            json.dump(report, fh, indent=2, allow_nan=False)
    return report
