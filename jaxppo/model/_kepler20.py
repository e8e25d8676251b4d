"""Kepler-20 b and c as in Mueller et al. (2021), and the synthetic data set
bundled as the default (Table 3 "This work"; T0 in BKJD = BJD - 2454833)."""

from __future__ import annotations

import numpy as np

from ._lightcurve import LightCurve
from ._phoenix import kepler20_star
from ._star import Star
from ._system import Planet, System
from ._transits import multi_transits

__all__ = ["kepler20_system", "PAPER_MULTI_TRANSITS", "paper_multi_transits", "simulate", "simulate_kepler20"]

# Mid-times of the seven b + c double transits listed in the paper (Sect. 3.3.1).
PAPER_MULTI_TRANSITS = (334.02, 670.45, 844.13, 1017.82, 1180.56, 1354.25, 1527.93)


def kepler20_system(star: Star | None = None, radius_scale: float = 1.0) -> System:
    """Kepler-20 b (tilted) and c with the paper's Table 3 "This work" values."""
    star = kepler20_star() if star is None else star
    b = Planet(period=3.69611590, t0=134.501962, a=10.60, inc=87.687, radius=0.01805 * radius_scale, name="b")
    c = Planet(period=10.85408479, t0=138.608470, a=22.764, inc=89.967, radius=0.02878 * radius_scale, name="c")
    return System(star, [b, c], tilted=0)


def paper_multi_transits(system: System):
    """The seven double transits of the paper, as MultiTransit events."""
    events = multi_transits(system, 300.0, 1600.0)
    return [min(events, key=lambda e: abs(e.mid - m)) for m in PAPER_MULTI_TRANSITS]


def simulate(system: System, t, noise: float = 4e-4, alpha: float = 0.0, case: str = "same", seed: int = 0) -> LightCurve:
    """Model flux at times t plus white Gaussian noise of standard deviation
    ``noise`` (seeded); the tilted planet at ``alpha`` [deg] in ``case``."""
    if not noise > 0:
        raise ValueError(f"noise must be > 0, got {noise}")
    t = np.asarray(t, float)
    model = np.asarray(system.flux(t, alpha=alpha, case=case))
    rng = np.random.default_rng(seed)
    return LightCurve(t, model + rng.normal(0.0, noise, t.size), np.full(t.size, noise))


def simulate_kepler20(seed: int = 0, noise: float = 4e-4, alpha: float | None = None, case: str = "same",
                      radius_scale: float = 1.0, cadence: float = 1.0 / 1440.0, margin: float = 0.05,
                      star: Star | None = None) -> LightCurve:
    """Synthetic 1-minute photometry of the seven Kepler-20 b + c double
    transits (0.05 d of margin), white noise ``noise`` per point. ``alpha``
    (deg, with ``case``) injects the tilt, and so a planet-planet occultation
    where the geometry gives one; None means the untilted system (alpha = 0).
    ``radius_scale`` enlarges both planets (the paper's sensitivity study)."""
    system = kepler20_system(star, radius_scale)
    events = paper_multi_transits(system)
    t = np.concatenate([np.arange(e.start - margin, e.end + margin, cadence) for e in events])
    return simulate(system, t, noise, 0.0 if alpha is None else alpha, case, seed)
