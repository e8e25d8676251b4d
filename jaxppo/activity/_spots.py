"""Few-spot inversion of one rotation chunk (Mueller et al. 2021, Sect. 2.4;
a spot model in the spirit of Ioannidis et al. 2016).

Model: circular dark spots of angular radius rho, latitude phi and
longitude lambda, fixed contrast c = 1 - I_spot / I_phot, on a star with
quadratic limb darkening (u1, u2), inclination i (90 deg = equator-on) and
rotation period P. In the small-spot limit (rho << 1 rad; Dorren 1987 for
finite spots) a visible spot removes

    dF / F0 = c I(mu) mu sin^2(rho) / (1 - u1 / 3 - u2 / 6),
    mu = cos(i) sin(phi) + sin(i) cos(phi) cos(2 pi (t - t_ref) / P - lambda),

(zero for mu <= 0; i is the angle between the rotation axis and the line
of sight), where I(mu) = 1 - u1 (1 - mu) - u2 (1 - mu)^2 and
F0 / pi = 1 - u1/3 - u2/6. A spot crosses the central meridian at
rotational phase lambda / 360 deg: the longitude reads directly on the
brightness map's phase axis.

Degeneracies (why the paper calls the sizes lower limits): the amplitude
of a spot scales as c sin^2(rho) times its mean mu, so contrast (spot
temperature) and area trade exactly; at i near 90 deg latitude changes the
amplitude by cos(phi) almost as area does (only the limb-darkened shape of
the dip tells them apart, below the noise for Kepler-20); and the unspotted
level is unknown (a free offset), so a spot that is always visible is
invisible. The fit therefore fixes c and puts the spots on the equator of
an equator-on star by default: the sizes it returns are the smallest spots
of contrast c that make the dips.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["SpotFit", "spot_flux", "fit_spots", "KEPLER20_SPOT_CONTRAST"]

# A spot 1000 K cooler than Kepler-20's 5495 K photosphere: blackbody
# intensity ratio at 650 nm (mid Kepler band) exp(-hc/(lambda k) (1/4495 -
# 1/5495)) = 0.41, so contrast 1 - 0.41 = 0.59.
KEPLER20_SPOT_CONTRAST = 0.59
"""Spot contrast 1 - I_spot / I_photosphere of a spot 1000 K cooler than
Kepler-20's 5495 K photosphere (blackbody ratio 0.41 at 650 nm, mid Kepler
band); the default of ``fit_spots``."""


def spot_flux(t, lon, lat, radius, contrast, period, inc=90.0, u1=0.495, u2=0.154, t_ref=0.0):
    """Relative flux change (<= 0) of small circular spots on a rotating star.

    In the small-spot limit (Dorren 1987 for finite spots) a visible spot
    removes dF / F0 = c I(mu) mu sin^2(rho) / (1 - u1/3 - u2/6), with
    mu = cos(i) sin(phi) + sin(i) cos(phi) cos(2 pi (t - t_ref) / P - lambda)
    (zero for mu <= 0) and I(mu) = 1 - u1 (1 - mu) - u2 (1 - mu)^2. A spot
    crosses the central meridian at rotational phase lambda / 360 deg.
    Written in JAX: differentiable and jit-compatible.

    Parameters
    ----------
    t : array_like
        Times [d], any shape.
    lon : array_like
        Spot longitudes lambda [deg], shape [n_spots].
    lat : array_like
        Spot latitudes phi [deg], shape [n_spots].
    radius : array_like
        Spot angular radii rho [deg], shape [n_spots] (small: the formula
        is poor beyond about 30 deg).
    contrast : float or array_like
        1 - I_spot / I_phot, in 0..1; scalar or shape [n_spots].
    period : float
        Rotation period P [d].
    inc : float, optional
        Stellar inclination i [deg], the angle between rotation axis and line
        of sight (default 90: equator-on).
    u1 : float, optional
        First quadratic limb-darkening coefficient (default 0.495: the
        paper's PHOENIX fit for Kepler-20).
    u2 : float, optional
        Second quadratic limb-darkening coefficient (default 0.154).
    t_ref : float, optional
        Time of rotational phase 0 [d] (default 0).

    Returns
    -------
    jax.Array
        Sum over spots of the flux change -dF / F0, the shape of ``t``.

    Examples
    --------
    A spot of radius 5 deg and contrast 0.59 on the equator: centred at
    t = 0, 45 deg from the centre at t = P / 8, behind the star at P / 2.

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> f = jp.activity.spot_flux(np.array([0.0, 2.5, 10.0]), [0.0], [0.0], [5.0], 0.59, 20.0)
    >>> f.shape
    (3,)
    >>> print(f"{float(f[0]):.6f} {float(f[1]):.6f} {bool(f[2] == 0)}")
    -0.005538 -0.003296 True
    """
    t = jnp.asarray(t, float)[..., None]
    lon, lat, rho = (jnp.deg2rad(jnp.asarray(v, float)) for v in (lon, lat, radius))
    inc = jnp.deg2rad(jnp.asarray(inc, float))
    phase = 2 * jnp.pi * (t - t_ref) / period
    mu = jnp.cos(inc) * jnp.sin(lat) + jnp.sin(inc) * jnp.cos(lat) * jnp.cos(phase - lon)
    mu_v = jnp.clip(mu, 0.0, 1.0)
    intensity = 1 - u1 * (1 - mu_v) - u2 * (1 - mu_v) ** 2
    norm = 1 - u1 / 3 - u2 / 6
    return -jnp.sum(jnp.asarray(contrast, float) * intensity * mu_v * jnp.sin(rho) ** 2, axis=-1) / norm


@dataclasses.dataclass(frozen=True)
class SpotFit:
    """A few-spot fit of one rotation chunk, made by ``fit_spots``.

    Attributes
    ----------
    lon : numpy.ndarray
        Spot longitudes [deg] in [0, 360), ascending, shape [n_spots]; a spot
        crosses the central meridian at phase lon / 360.
    lat : numpy.ndarray
        Spot latitudes [deg] (fixed in the fit), shape [n_spots].
    radius : numpy.ndarray
        Spot angular radii [deg], shape [n_spots] (lower limits: contrast,
        latitude and size are degenerate).
    offset : float
        The unspotted level, in the units of the fitted flux.
    contrast : float
        Spot contrast 1 - I_spot / I_phot (fixed).
    inc : float
        Stellar inclination [deg] (fixed).
    period : float
        Rotation period [d].
    t_ref : float
        Time of rotational phase 0 [d].
    chi2 : float
        Chi-square of the fit with errors ``sigma``.
    sigma : float
        The flux error per point used in ``chi2``.
    success : bool
        True when optimistix's Levenberg-Marquardt converged.

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> fit = jp.activity.SpotFit(lon=np.array([90.0]), lat=np.array([0.0]), radius=np.array([5.0]),
    ...                           offset=1e-4, contrast=0.59, inc=90.0, period=20.0, t_ref=0.0,
    ...                           chi2=0.0, sigma=1e-4, success=True)
    >>> print(f"{float(fit.model([5.0])[0]):.6f}")  # the spot at disk centre at t = P / 4
    -0.005438
    """

    lon: np.ndarray
    lat: np.ndarray
    radius: np.ndarray
    offset: float
    contrast: float
    inc: float
    period: float
    t_ref: float
    chi2: float
    sigma: float
    success: bool

    def model(self, t):
        """The fitted light curve: ``offset`` plus ``spot_flux`` of the spots.

        Parameters
        ----------
        t : array_like
            Times [d], any shape.

        Returns
        -------
        numpy.ndarray
            Relative flux, the shape of ``t``.
        """
        return np.asarray(self.offset + spot_flux(t, self.lon, self.lat, self.radius, self.contrast,
                                                  self.period, self.inc, t_ref=self.t_ref))


_MAX_RADIUS = 30.0  # [deg]: beyond this the small-spot formula is poor


def _unpack(theta):
    """theta = (longitudes [deg], radius logits, offset); radius = 30 deg x sigmoid."""
    n = (theta.shape[0] - 1) // 2
    return theta[:n], _MAX_RADIUS * jax.nn.sigmoid(theta[n:2 * n]), theta[-1]


def _residuals(theta, args):
    t, y, w, lat, contrast, period, inc, u1, u2, t_ref = args
    lon, radius, offset = _unpack(theta)
    lat_s = jnp.full(lon.shape, lat)
    return w * (y - offset - spot_flux(t, lon, lat_s, radius, contrast, period, inc, u1, u2, t_ref))


@eqx.filter_jit
def _solve(theta0, args, max_steps):
    import optimistix as optx

    solver = optx.LevenbergMarquardt(rtol=1e-8, atol=1e-10)
    sol = optx.least_squares(_residuals, solver, theta0, args=args, max_steps=max_steps, throw=False)
    return sol.value, sol.result == optx.RESULTS.successful


def fit_spots(time, flux, period: float, n_spots: int = 2, contrast: float = KEPLER20_SPOT_CONTRAST,
              inc: float = 90.0, lat: float = 0.0, t_ref: float | None = None, sigma: float | None = None,
              n_starts: int = 8, u1: float = 0.495, u2: float = 0.154, max_steps: int = 400) -> SpotFit:
    """Fit a few spots to one rotation chunk of relative flux.

    Least squares (optimistix Levenberg-Marquardt) of ``n_spots`` spots'
    longitudes and radii, plus the unspotted level, with the small-spot
    model of ``spot_flux`` (Mueller et al. 2021, Sect. 2.4; in the
    spirit of Ioannidis et al. 2016). Latitude ``lat``, contrast and
    inclination are fixed: contrast and area trade exactly, at i near 90 deg
    latitude changes the amplitude almost as area does, and the unspotted
    level is free, so the radii returned are the smallest spots of contrast
    ``contrast`` that make the dips (lower limits). Radii are kept below
    30 deg. ``n_starts`` sets of starting longitudes (evenly spread, rotated)
    are tried and the lowest chi2 kept.

    Parameters
    ----------
    time : array_like
        Times [d], shape [n_times], finite, at least 10 points.
    flux : array_like
        Relative flux, shape [n_times], finite.
    period : float
        Rotation period [d].
    n_spots : int, optional
        Number of spots, 1 to 6 (default 2).
    contrast : float, optional
        Spot contrast 1 - I_spot / I_phot, in (0, 1] (default 0.59: a spot
        1000 K cooler than Kepler-20's 5495 K photosphere, at 650 nm).
    inc : float, optional
        Stellar inclination [deg], in [0, 180] (default 90: equator-on).
    lat : float, optional
        Latitude of every spot [deg], in [-90, 90] (default 0).
    t_ref : float, optional
        Time of rotational phase 0 [d]; None (default): the first time.
    sigma : float, optional
        Flux error per point; None (default): the point-to-point scatter,
        1.4826 MAD(diff(flux)) / sqrt(2).
    n_starts : int, optional
        Number of starting longitude sets (default 8).
    u1 : float, optional
        First quadratic limb-darkening coefficient (default 0.495).
    u2 : float, optional
        Second quadratic limb-darkening coefficient (default 0.154).
    max_steps : int, optional
        Levenberg-Marquardt step limit per start (default 400).

    Returns
    -------
    SpotFit
        The best fit: spot longitudes (ascending), latitudes, radii, the
        unspotted level, chi2 and the fixed parameters.

    Raises
    ------
    ValueError
        If ``time`` and ``flux`` are not 1D of equal length >= 10 or not
        finite; if ``period`` is not positive, ``n_spots`` not an integer in
        1..6, ``contrast`` outside (0, 1], ``inc`` outside [0, 180], ``lat``
        outside [-90, 90], ``n_starts`` not a positive integer, or ``sigma``
        (given or estimated) not positive.

    Examples
    --------
    A spot of radius 5 deg at longitude 90 deg, injected with noise of 1e-4,
    is recovered:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> rng = np.random.default_rng(1)
    >>> t = np.linspace(0.0, 20.0, 400)
    >>> spot = jp.activity.spot_flux(t, [90.0], [0.0], [5.0], 0.59, 20.0)
    >>> y = 2e-4 + np.asarray(spot) + 1e-4 * rng.normal(size=t.size)
    >>> fit = jp.activity.fit_spots(t, y, 20.0, n_spots=1, t_ref=0.0, n_starts=2)
    >>> print(f"lon {fit.lon[0]:.1f} deg, radius {fit.radius[0]:.2f} deg, converged: {fit.success}")
    lon 90.0 deg, radius 5.00 deg, converged: True
    >>> print(f"offset {fit.offset:.5f}, chi2 per point {fit.chi2 / t.size:.2f}")
    offset 0.00019, chi2 per point 0.82
    """
    t = np.asarray(time, float)
    y = np.asarray(flux, float)
    if t.ndim != 1 or t.size < 10 or y.shape != t.shape:
        raise ValueError(f"time and flux must be 1D of equal length >= 10, got {t.shape}, {y.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise ValueError("time and flux must be finite")
    if not (np.isfinite(period) and period > 0):
        raise ValueError(f"period must be > 0 days, got {period!r}")
    if not isinstance(n_spots, (int, np.integer)) or not 1 <= n_spots <= 6:
        raise ValueError(f"n_spots must be an integer in 1..6, got {n_spots!r}")
    if not 0 < contrast <= 1:
        raise ValueError(f"contrast must be in (0, 1], got {contrast!r}")
    if not 0 <= inc <= 180:
        raise ValueError(f"inc must be in [0, 180] degrees, got {inc!r}")
    if not -90 <= lat <= 90:
        raise ValueError(f"lat must be in [-90, 90] degrees, got {lat!r}")
    if not isinstance(n_starts, (int, np.integer)) or n_starts < 1:
        raise ValueError(f"n_starts must be a positive integer, got {n_starts!r}")
    t_ref = float(t.min()) if t_ref is None else float(t_ref)
    if sigma is None:
        # point-to-point scatter: robust to the slow spot signal itself
        sigma = 1.4826 * np.median(np.abs(np.diff(y))) / np.sqrt(2)
    if not sigma > 0:
        raise ValueError(f"sigma must be > 0, got {sigma!r}")
    # pad to a multiple of 256 points with zero weight, so chunks of
    # different lengths share one compiled solver
    n_pad = -(-t.size // 256) * 256
    w = np.zeros(n_pad)
    w[: t.size] = 1.0 / sigma
    args = (jnp.asarray(np.pad(t, (0, n_pad - t.size), mode="edge")), jnp.asarray(np.pad(y, (0, n_pad - t.size))),
            jnp.asarray(w), jnp.asarray(float(lat)), jnp.asarray(float(contrast)), jnp.asarray(float(period)),
            jnp.asarray(float(inc)), jnp.asarray(float(u1)), jnp.asarray(float(u2)), jnp.asarray(t_ref))
    best = None
    for k in range(n_starts):
        lon0 = (360.0 * (np.arange(n_spots) / n_spots + k / (n_starts * n_spots))) % 360.0
        theta0 = jnp.asarray(np.concatenate([lon0, np.full(n_spots, -1.0), [float(np.max(y))]]))
        theta, ok = _solve(theta0, args, max_steps)
        chi2 = float(jnp.sum(_residuals(theta, args) ** 2))
        if np.isfinite(chi2) and (best is None or chi2 < best[1]):
            best = (theta, chi2, bool(ok))
    theta, chi2, ok = best
    lon, radius, offset = (np.asarray(v) for v in _unpack(theta))
    order = np.argsort(lon % 360.0)
    return SpotFit((lon % 360.0)[order], np.full(n_spots, float(lat)), radius[order], float(offset),
                   float(contrast), float(inc), float(period), t_ref, chi2, float(sigma), ok)
