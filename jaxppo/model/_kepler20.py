"""Kepler-20 b and c as in Mueller et al. (2021), and the synthetic data set
bundled as the default (Table 3 "This work"; T0 in BKJD = BJD - 2454833)."""

from __future__ import annotations

import numpy as np

from ._lightcurve import LightCurve
from ._phoenix import kepler20_star
from ._star import Star
from ._planet import Planet
from ._system import System
from ._units import from_quantity
from ._transits import multi_transits

__all__ = ["kepler20_system", "PAPER_MULTI_TRANSITS", "paper_multi_transits", "simulate", "simulate_kepler20", "injection_note"]

# Mid-times of the seven b + c double transits listed in the paper (Sect. 3.3.1).
PAPER_MULTI_TRANSITS = (334.02, 670.45, 844.13, 1017.82, 1180.56, 1354.25, 1527.93)


def kepler20_system(star: Star | None = None, radius_scale: float = 1.0) -> System:
    """Build Kepler-20 b (tilted) and c with the values of Mueller et al. (2021), Table 3 "This work".

    t0 in BKJD (BJD - 2454833); circular orbits.

    Parameters
    ----------
    star : Star or None, optional
        The star; default ``kepler20_star`` (non-linear limb darkening
        fitted to PHOENIX-ACES intensities, Teff 5500 K).
    radius_scale : float, optional
        Factor on both planets' radii (default 1; the paper's sensitivity
        study enlarges them).

    Returns
    -------
    System
        Planets "b" (tilted, index 0) and "c".

    Examples
    --------
    >>> import jaxppo as jp
    >>> system = jp.kepler20_system()
    >>> [p.name for p in system.planets], system.tilted
    (['b', 'c'], 0)
    >>> system.planets[1]
    Planet(name='c', period=10.85408479 d, t0=138.60847 d, a=22.764 R*, inc=89.967 deg, radius=0.02878)
    >>> print(f"{float(jp.kepler20_system(radius_scale=2.0).planets[0].radius):.5f}")
    0.03610
    """
    star = kepler20_star() if star is None else star
    b = Planet(period=3.69611590, t0=134.501962, a=10.60, inc=87.687, radius=0.01805 * radius_scale, name="b")
    c = Planet(period=10.85408479, t0=138.608470, a=22.764, inc=89.967, radius=0.02878 * radius_scale, name="c")
    return System(star, [b, c], tilted=0)


def paper_multi_transits(system: System):
    """The seven double transits of the paper, as MultiTransit events."""
    events = multi_transits(system, 300.0, 1600.0)
    return [min(events, key=lambda e: abs(e.mid - m)) for m in PAPER_MULTI_TRANSITS]


def simulate(system: System, t, noise: float = 4e-4, alpha: float = 0.0, case: str = "same", seed: int = 0) -> LightCurve:
    """Simulate photometry: the model flux at times t plus white Gaussian noise.

    Parameters
    ----------
    system : System
        The star and planets.
    t : array_like or Quantity or TimeDelta
        Times [d] (a time Quantity or TimeDelta is converted to days),
        shape [n_times], distinct.
    noise : float or Quantity, optional
        Standard deviation of the noise per point (relative flux, or a
        dimensionless Quantity such as ``0.01 * u.percent``; default 4e-4), > 0;
        also the ``flux_err`` of every point.
    alpha : float, optional
        Tilt of the tilted planet's orbit [deg] (default 0).
    case : str or tuple of int, optional
        Hemisphere case (default "same"; see ``System.flux``).
    seed : int, optional
        Seed of the noise (``numpy.random.default_rng``; default 0).

    Returns
    -------
    LightCurve
        The noisy flux with errors ``noise``, sorted by time, no exposure.

    Raises
    ------
    ValueError
        When ``noise`` is not one number > 0, or ``t`` or ``noise`` is a
        Quantity of the wrong kind (a length for t, a time for noise).

    Examples
    --------
    A transit of Kepler-20 c with 100 ppm noise:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> system = jp.kepler20_system()
    >>> t = np.linspace(138.5, 138.7, 201)
    >>> lc = jp.simulate(system, t, noise=1e-4, seed=1)
    >>> residual = lc.flux - np.asarray(system.flux(t))
    >>> print(len(lc), lc.flux_err[0], f"{np.std(residual):.1e}")
    201 0.0001 9.3e-05
    """
    noise = from_quantity("noise", noise, "")
    if not np.ndim(noise) == 0 or not noise > 0:
        raise ValueError(f"noise must be one number > 0, got {noise}")
    noise = float(noise)
    # a time Quantity or TimeDelta in days (its bare values were taken as days)
    t = np.asarray(from_quantity("t", t, "d"), float)
    model = np.asarray(system.flux(t, alpha=alpha, case=case))
    rng = np.random.default_rng(seed)
    return LightCurve(t, model + rng.normal(0.0, noise, t.size), np.full(t.size, noise))


def simulate_kepler20(seed: int = 0, noise: float = 4e-4, alpha: float | None = None, case: str = "same",
                      radius_scale: float = 1.0, cadence: float = 1.0 / 1440.0, margin: float = 0.05,
                      star: Star | None = None) -> LightCurve:
    """Simulate 1-minute photometry of the seven Kepler-20 b + c double transits.

    The double transits that Mueller et al. (2021, Sect. 3.3.1) list, from
    first to last contact with a margin on each side, modelled with
    ``kepler20_system`` and white noise (``simulate``).

    Parameters
    ----------
    seed : int, optional
        Seed of the noise (default 0).
    noise : float, optional
        Standard deviation of the noise per point (default 4e-4), > 0.
    alpha : float or None, optional
        Tilt of planet b's orbit [deg], with ``case``: injects the tilt, and
        so a planet-planet occultation where the geometry gives one. None
        (default): the untilted system (alpha = 0).
    case : str, optional
        Hemisphere case (default "same").
    radius_scale : float, optional
        Factor on both planets' radii (default 1; the paper's sensitivity
        study).
    cadence : float, optional
        Spacing of the time stamps [d] (default 1 min).
    margin : float, optional
        Out-of-transit time before and after each event [d] (default 0.05).
    star : Star or None, optional
        The star; default ``kepler20_star``.

    Returns
    -------
    LightCurve
        Times [d, BKJD], noisy flux and errors ``noise``; no exposure.

    Raises
    ------
    ValueError
        When ``noise`` is not > 0.

    Examples
    --------
    With a 0.01-d cadence (the default is 1 min). The same seed gives the
    same noise, so the difference of two simulations is the planet-planet
    occultation signal that alpha = 90 deg injects:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> lc = jp.simulate_kepler20(cadence=0.01)
    >>> print(len(lc), f"{lc.time[0]:.3f}", f"{lc.time[-1]:.3f}")
    206 333.854 1528.053
    >>> tilted = jp.simulate_kepler20(cadence=0.01, alpha=90.0)
    >>> print(f"{1e6 * np.max(np.abs(tilted.flux - lc.flux)):.0f} ppm")
    386 ppm
    """
    system = kepler20_system(star, radius_scale)
    events = paper_multi_transits(system)
    t = np.concatenate([np.arange(e.start - margin, e.end + margin, cadence) for e in events])
    return simulate(system, t, noise, 0.0 if alpha is None else alpha, case, seed)


def injection_note(system, time, alpha: float, case: str) -> str:
    """Which double transits in the simulated data (times ``time`` [d])
    carry a planet-planet occultation at the injected tilt ``alpha`` [deg]
    and ``case``, as a line of text (``jaxppo simulate`` prints it): a
    tilt without any gives data without a PPO signal, nothing for a scan
    to recover."""
    from ._overlap import ppo_table

    time = np.asarray(time, float)
    events = multi_transits(system, float(time.min()), float(time.max()))
    frames = [time[(time >= e.start) & (time <= e.end)] for e in events]
    events, frames = [e for e, f in zip(events, frames) if f.size], [f for f in frames if f.size]  # those with data
    hit = ppo_table(system, frames, np.array([float(alpha)]), case)[0]
    if not hit.any():
        return (f"no PPO at alpha {alpha:g} deg (case {case}) in any of the {len(events)} double transits: the data "
                "carry no occultation signal to recover (a larger --radius-scale widens the tilts that give one)")
    mids = ", ".join(f"{e.mid:.2f}" for e, h in zip(events, hit) if h)
    return f"PPO at alpha {alpha:g} deg (case {case}) in {int(hit.sum())} of {len(events)} double transits (BKJD {mids})"
