"""First and last contact of a transit on an eccentric orbit, solved on the
host on the exact orbit (``jaxppo.Planet.contacts``)."""

from __future__ import annotations

import math

import numpy as np

from ..core.geometry import conjunction_mean_anomaly

__all__ = ["eccentric_contacts"]


def _bisect(g, lo, hi, steps=200):
    """Root of g in [lo, hi] (g(lo), g(hi) of opposite signs) to rounding."""
    glo = g(lo)
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        gm = g(mid)
        if (gm < 0) == (glo < 0):
            lo, glo = mid, gm
        else:
            hi = mid
    return 0.5 * (lo + hi)


def eccentric_contacts(period, a, inc, radius, e, omega) -> tuple[float, float]:
    """(t1 - t0, t4 - t0) [d] of an eccentric orbit: the outermost times
    about conjunction at which the sky distance equals 1 + radius, on the
    near side (z > 0). Works in theta = f + omega - pi/2 (0 at conjunction),
    where r = a (1 - e^2) / (1 + e cos f) and the sky distance is
    r sqrt(sin^2 theta + cos^2 theta cos^2 i)."""
    w = math.radians(omega) - 0.5 * math.pi
    ci = math.cos(math.radians(inc))
    lim = 1.0 + radius

    def dist(th):
        r = a * (1.0 - e * e) / (1.0 + e * np.cos(th - w))
        return r * np.sqrt(np.sin(th) ** 2 + (np.cos(th) * ci) ** 2) - lim

    grid = np.linspace(-0.5 * np.pi, 0.5 * np.pi, 4097)
    d = dist(grid)
    k = int(np.argmin(d))
    if d[k] >= 0:
        # refine the minimum (a grazing transit may dip below 1 + radius
        # between grid points): golden-section search on the two cells
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        g = (math.sqrt(5.0) - 1.0) / 2.0
        for _ in range(100):
            m1, m2 = hi - g * (hi - lo), lo + g * (hi - lo)
            if dist(m1) < dist(m2):
                hi = m2
            else:
                lo = m1
        tmin = 0.5 * (lo + hi)
        if dist(tmin) >= 0:
            return 0.0, 0.0
        grid = np.insert(grid, k + 1 if tmin > grid[k] else k, tmin)
        d = dist(grid)
    inside = np.nonzero(d < 0)[0]
    # the ends of the half orbit are at distance r >= a (1 - e) > 1 + radius
    j0, j1 = inside[0], inside[-1]
    th1 = _bisect(lambda th: float(dist(th)), grid[j0 - 1], grid[j0])
    th4 = _bisect(lambda th: float(dist(th)), grid[j1], grid[j1 + 1])
    mc = float(conjunction_mean_anomaly(e, math.radians(omega), np))

    def dt(th):
        f = th - w
        E = 2.0 * math.atan2(math.sqrt(1.0 - e) * math.sin(0.5 * f), math.sqrt(1.0 + e) * math.cos(0.5 * f))
        dm = (E - e * math.sin(E)) - mc
        return period * math.remainder(dm, 2.0 * math.pi) / (2.0 * math.pi)

    return dt(th1), dt(th4)
