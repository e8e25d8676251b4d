"""The exposure rule: ONE home for how a model is averaged over an exposure.

A cadence of length ``exposure`` [d] centred on ``t`` integrates the flux
over [t - exposure / 2, t + exposure / 2]. Every model of jaxppo evaluates
the flux at ``n`` sub-exposure midpoints (the midpoint rule) and averages
each group of ``n``: ``supersampled_times`` gives the times,
``exposure_mean`` the average. ``LightCurve.supersampled_times`` is the
user-facing call; fits, scans and the PPO-or-spot step all go through here.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SUB_EXPOSURE", "sub_exposures", "supersampled_times", "exposure_mean"]

# [d] longest sub-exposure of the default exposure average. Why 30 s: a
# Kepler-20 b ingress and a planet-planet occultation last only 3-9 min; with
# 2-min sub-exposures (n = 15) the scan's Delta chi^2 was off by up to 0.08
# (tests/obliquity/test_scan.py checks the default against a 401-point average).
SUB_EXPOSURE = 0.5 / 1440.0


def sub_exposures(exposure: float) -> int:
    """The default number of sub-exposures of one cadence of ``exposure``
    [d]: the smallest odd n with exposure / n <= SUB_EXPOSURE (59 for a
    29.4-min Kepler long cadence; odd, so that one midpoint is the
    cadence's own time)."""
    exposure = float(exposure)
    if not np.isfinite(exposure) or exposure < 0:
        raise ValueError(f"exposure must be a finite number of days >= 0, got {exposure!r}")
    n = max(1, int(np.ceil(exposure / SUB_EXPOSURE)))
    return n + 1 - n % 2


def supersampled_times(time, exposure: float | None, n: int | None = None) -> tuple[np.ndarray, int]:
    """Times [d] at which to evaluate a model so that averaging consecutive
    groups of ``n`` (``exposure_mean``) reproduces each exposure.

    Args:
        time: cadence mid-times [d], 1D.
        exposure: cadence length [d]; None: instantaneous (the times as they
            are, n = 1).
        n: sub-exposures per cadence (default ``sub_exposures``).

    Returns:
        (times [time * n], n): sub-exposure midpoints, cadence by cadence.
    """
    time = np.asarray(time)
    if exposure is None:
        return time, 1
    if n is None:
        n = sub_exposures(exposure)
    elif isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n (sub-exposures per cadence) must be a positive integer, got {n!r}")
    off = (np.arange(n) + 0.5) / n - 0.5
    return (time[:, None] + off[None, :] * exposure).ravel(), int(n)


def exposure_mean(model, n: int):
    """The exposure average of a model at ``supersampled_times``: the
    mean of each consecutive group of ``n`` along the last axis ([..., time
    * n] -> [..., time]). NumPy or JAX arrays (inside ``jit`` too)."""
    return model.reshape(*model.shape[:-1], -1, n).mean(-1)
