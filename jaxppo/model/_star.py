"""Star: a radially symmetric intensity profile I(mu) with exact totals."""

from __future__ import annotations

import dataclasses
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ..core import intensity as _I
from ._programs import stored

__all__ = ["Star", "Spots", "LAWS"]

LAWS = ("uniform", "quadratic", "nonlinear", "power2", "tabulated")
_INTERPOLATIONS = ("sqrt-poly", "linear", "cubic")


def _check_mu_nodes(mu_np: np.ndarray, pad_ends: bool) -> None:
    """The nodes of a tabulated profile (see ``Star.tabulated``)."""
    if mu_np.size < 3:
        raise ValueError(f"a tabulated profile needs at least 3 points, got {mu_np.size}")
    _check_finite("mu", mu_np)
    if np.any(mu_np < 0) or np.any(mu_np > 1):
        raise ValueError(f"mu must lie in [0, 1], got values from {mu_np.min()} to {mu_np.max()}")
    if np.any(np.diff(mu_np) <= 0):
        raise ValueError("mu must be strictly increasing (sort the table and drop repeats)")
    if (mu_np[0] > 0 or mu_np[-1] < 1) and not pad_ends:
        raise ValueError(
            f"mu must reach 0 and 1 (the whole disk), got a table from mu = {mu_np[0]:g} to {mu_np[-1]:g}: "
            "beyond it I(mu) would be invented by the interpolation. Extend the table with the intensity you "
            "assume there (e.g. a node at mu = 0), or pass pad_ends=True to repeat the end values at mu = 0 "
            "and 1 (flat beyond the table only with interpolation='linear')"
        )


def _check_finite(name: str, value) -> None:
    if isinstance(value, jax.core.Tracer):
        return
    # a quoted number or a bool is a typo (True became u1 = 1), not a coefficient
    if isinstance(value, (str, bytes, bool, np.bool_)) or np.asarray(value).dtype.kind in "bUSO":
        raise ValueError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    # a coefficient is a plain number: a Quantity in percent, degrees or
    # seconds would have its bare value used (0.4 % as 0.4)
    if hasattr(value, "unit") and str(getattr(value, "unit", "")) != "":
        raise ValueError(f"{name} must be a plain number (a limb-darkening coefficient), got the Quantity {value!r}")
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")


def _check_coefficient(name: str, value) -> None:
    """``_check_finite`` for one limb-darkening coefficient, which must be
    one number (a Star holds one profile)."""
    _check_finite(name, value)
    if not isinstance(value, jax.core.Tracer) and np.ndim(value) != 0:
        raise ValueError(f"{name} must be one number (a Star holds one profile), got shape {np.shape(value)}: "
                         f"{value!r}")


def _is_traced(*values) -> bool:
    return any(isinstance(v, jax.core.Tracer) for v in values)


# where _check_profile looks for a negative intensity (dense near the limb)
_CHECK_MU = np.concatenate([np.linspace(0.0, 1.0, 2001), np.geomspace(1e-12, 1e-3, 61)])


@stored(filtered=True)
def _profile(star: "Star", mu):
    """(F0, I(mu)) in one program (a stored one: a new process loads it;
    eager, the two took 0.5 s of every command)."""
    return star.total_flux, star.intensity(mu)


def _plain(v) -> str:
    """A coefficient as an error message shows it: a NumPy number as the
    plain number (5.0, not np.float64(5.0)), anything else as its repr."""
    if isinstance(v, (np.floating, np.integer)) and not isinstance(v, np.bool_):
        return repr(v.item())
    return repr(v)


def _check_profile(star: "Star", coefficients: str) -> "Star":
    """Refuse a law whose total flux F0 is not positive (the normalisation
    would flip or blow up every light curve) and warn when its intensity is
    negative somewhere on mu in [0, 1] (not a star's, though the engine
    integrates it exactly). Traced coefficients are not checked."""
    if _is_traced(star.params):
        return star
    f0, inten = (np.asarray(v) for v in _profile(star, _CHECK_MU))
    f0 = float(f0)
    # zero to rounding (u1 = 3, u2 = 0 gives F0 = 0 exactly, or -3e-16 as
    # compiled) is zero: a light curve normalised by it is noise times 1e16
    rounding = 1e-12 * np.pi * float(np.max(np.abs(inten)))
    if not f0 > rounding:
        raise ValueError(
            f"Star.{star.law}({coefficients}) has total flux F0 = {0.0 if abs(f0) <= rounding else f0:.6g} <= 0: "
            "no physical star; "
            "check the coefficients"
        )
    if np.min(inten) < 0:
        j = int(np.argmin(inten))
        warnings.warn(
            f"Star.{star.law}({coefficients}) has negative intensity I(mu={_CHECK_MU[j]:.3g}) = {inten[j]:.3g} "
            "(relative to the centre): not a physical profile",
            UserWarning,
            stacklevel=3,
        )
    return star


def _sqrt_poly_design(mu: np.ndarray, degree: int) -> np.ndarray:
    """Chebyshev design matrix in x = 2 sqrt(mu) - 1 (well conditioned)."""
    from numpy.polynomial import chebyshev as C

    return C.chebvander(2.0 * np.sqrt(mu) - 1.0, degree)


def _choose_degree(mu: np.ndarray, inten: np.ndarray, max_degree: int, rtol: float) -> int:
    """Smallest degree of the sqrt(mu) polynomial whose max residual at the
    table points is below rtol * max(I) (or ``max_degree``)."""
    scale = np.max(np.abs(inten))
    limit = min(max_degree, len(mu) - 1)
    for deg in range(2, limit + 1):
        design = _sqrt_poly_design(mu, deg)
        coef, *_ = np.linalg.lstsq(design, inten, rcond=None)
        if np.max(np.abs(design @ coef - inten)) <= rtol * scale:
            return deg
    design = _sqrt_poly_design(mu, limit)
    coef, *_ = np.linalg.lstsq(design, inten, rcond=None)
    resid = float(np.max(np.abs(design @ coef - inten)) / scale)
    warnings.warn(
        f"Star.tabulated: no sqrt(mu) polynomial of degree <= {limit} meets rtol = {rtol:g} (max residual "
        f"{resid:.2g} of max(I) at degree {limit}); the table is smoothed. Use interpolation='linear' or 'cubic' "
        "for a profile with kinks, or raise max_degree",
        stacklevel=3,
    )
    return limit


def _deg_array(name: str, value, ndim: int) -> Array:
    _check_finite(name, value)
    arr = jnp.asarray(value, float)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {'a 1D array (one value per spot)' if ndim else 'a scalar'}, got shape {arr.shape}")
    return arr


class Spots(eqx.Module):
    """Circular spots on a rotating star (Mueller et al. 2021, Sect. 2.4).

    Every field but ``edge`` is an array, so ``jax.grad`` sees them (spot
    sizes, positions, contrasts and the rotation are fit parameters). The
    raster that models a spotted star places its pixel window on the host,
    so such a flux is differentiated in eager calls with respect to the
    spots and the star only; ``jax.jit`` of it, and ``jax.grad`` with
    respect to the disks' positions or radii (the planets' parameters),
    raise (JAX cannot convert the traced positions to place the window).
    Attach them to a star with ``Star.with_spots``; only the raster
    models a spotted star, and its flux is relative to the unspotted star's
    total flux F0 (docs/activity.md). Spots must not overlap: contrasts add
    (1 - sum_k c_k S_k).

    Parameters
    ----------
    lat : array_like
        Latitude of each spot [deg], in [-90, 90]; a scalar or [n_spots].
    lon : array_like
        Longitude of each spot [deg], a scalar or [n_spots]: the rotational
        phase (x 360 deg) at which the spot crosses the central meridian, as
        in ``jaxppo.activity.spot_flux``.
    radius : array_like
        Angular radius of each spot [deg], in (0, 90); a scalar or [n_spots].
    contrast : array_like
        1 - I_spot / I_phot per spot, <= 1 (1: black; < 0: a facula); a
        scalar or [n_spots]. ``lat``, ``lon``, ``radius`` and ``contrast``
        broadcast to one length, the number of spots.
    period : float
        Rotation period [d], > 0.
    inc : float, optional
        Angle between the rotation axis and the line of sight [deg], in
        [0, 180] (default 90: equator-on). The axis points to +y on the sky,
        rotated by ``obliquity``.
    t_ref : float, optional
        Time of rotational phase 0 [d] (default 0).
    obliquity : float, optional
        Rotation of the axis on the sky [deg] (default 0), the way
        ``System``'s ``alpha`` rotates the tilted planet's orbit, so a star
        with obliquity = alpha spins with that orbit; spots near the central
        meridian move to +x, like a transiting planet.
    edge : float, optional
        Width of the smooth (C1, cubic smoothstep) edge [deg], in (0, 30)
        (default 0.5; static, not traced): the contrast falls from c to 0
        over radius +- edge/2 in angular distance. The edge keeps the
        raster's flux smooth in the spot parameters (finite, useful
        gradients); a hard edge is the limit edge -> 0 (the raster's pixels
        must stay several times smaller).

    Attributes
    ----------
    lat, lon, radius, contrast : jax.Array
        As above, broadcast to [n_spots].
    period, inc, t_ref, obliquity : jax.Array
        As above, 0-d arrays.
    edge : float
        As above.

    Raises
    ------
    ValueError
        When a value is not finite, ``lat``, ``lon``, ``radius`` or
        ``contrast`` is more than 1D or their lengths do not broadcast,
        ``period``, ``inc``, ``t_ref`` or ``obliquity`` is not a scalar,
        ``edge`` is not a number in (0, 30), or a concrete value is out of
        its range (lat in [-90, 90], radius in (0, 90), contrast <= 1,
        period > 0, inc in [0, 180]).

    Examples
    --------
    One half-dark spot at latitude 20 deg on an equator-on star; with no
    planet on the disk the flux is the rotational modulation:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> spots = jp.Spots(lat=20.0, lon=0.0, radius=10.0, contrast=0.5, period=10.0)
    >>> spots.n
    1
    >>> star = jp.Star.quadratic(0.4, 0.25).with_spots(spots)
    >>> t = np.array([0.0, 2.5, 5.0])  # [d]: spot at the centre, near the limb, behind the star
    >>> f = jp.occultation_flux(star, x=np.full((3, 1), 5.0), y=0.0, r=0.1, times=t)  # a planet off the star
    >>> print(np.round(np.asarray(f), 6))
    [0.983305 0.999701 1.      ]
    """

    lat: Array
    lon: Array
    radius: Array
    contrast: Array
    period: Array
    inc: Array
    t_ref: Array
    obliquity: Array
    edge: float = eqx.field(static=True, default=0.5)

    def __init__(self, lat, lon, radius, contrast, period, inc=90.0, t_ref=0.0, obliquity=0.0, edge=0.5):
        for name, v in (("lat", lat), ("lon", lon), ("radius", radius), ("contrast", contrast)):
            _check_finite(name, v)
        lat, lon, radius, contrast = (jnp.atleast_1d(jnp.asarray(v, float)) for v in (lat, lon, radius, contrast))
        for name, v in (("lat", lat), ("lon", lon), ("radius", radius), ("contrast", contrast)):
            if v.ndim != 1:
                raise ValueError(f"{name} must be a scalar or a 1D array over spots, got shape {v.shape}")
        try:
            n = np.broadcast_shapes(lat.shape, lon.shape, radius.shape, contrast.shape)
        except ValueError:
            raise ValueError(
                f"lat, lon, radius, contrast must have one value per spot, got shapes "
                f"{lat.shape}, {lon.shape}, {radius.shape}, {contrast.shape}"
            ) from None
        self.lat, self.lon, self.radius, self.contrast = (jnp.broadcast_to(v, n) for v in (lat, lon, radius, contrast))
        self.period = _deg_array("period", period, 0)
        self.inc = _deg_array("inc", inc, 0)
        self.t_ref = _deg_array("t_ref", t_ref, 0)
        self.obliquity = _deg_array("obliquity", obliquity, 0)
        if not (isinstance(edge, (int, float, np.floating, np.integer)) and 0 < float(edge) < 30):
            raise ValueError(f"edge must be a number of degrees in (0, 30), got {edge!r}")
        self.edge = float(edge)
        checks = (
            ("lat", self.lat, lambda v: np.all(np.abs(v) <= 90), "in [-90, 90] deg"),
            ("radius", self.radius, lambda v: np.all((v > 0) & (v < 90)), "in (0, 90) deg"),
            ("contrast", self.contrast, lambda v: np.all(v <= 1), "<= 1 (1: a black spot)"),
            ("period", self.period, lambda v: v > 0, "> 0 [d]"),
            ("inc", self.inc, lambda v: 0 <= v <= 180, "in [0, 180] deg"),
        )
        for name, v, ok, what in checks:
            if not _is_traced(v) and not ok(np.asarray(v)):
                raise ValueError(f"spot {name} must be {what}, got {np.asarray(v)!r}")

    @property
    def n(self) -> int:
        """Number of spots (the length of ``lat``)."""
        return self.lat.shape[0]


class Star(eqx.Module):
    """A radially symmetric star of unit radius.

    Build it with one of the constructors; every profile is normalised by its
    exact total flux F0 = 2 pi int_0^1 I(mu) mu dmu (a 1D closed form, never a
    pixel sum).

    Laws (intensity relative to the centre, mu = sqrt(1 - r^2)):

    * ``Star.uniform()``: I = 1.
    * ``Star.quadratic(u1, u2)``: I = 1 - u1 (1 - mu) - u2 (1 - mu)^2.
    * ``Star.nonlinear(c1, c2, c3, c4)``: I = 1 - sum_k c_k (1 - mu^(k/2))
      (Claret 2000).
    * ``Star.power2(c, alpha)``: I = 1 - c (1 - mu^alpha) (Hestroffer 1997;
      Claret & Southworth 2023 tabulate c as ``g`` and alpha as ``h``).
    * ``Star.tabulated(mu, intensity, interpolation=...)``: any (mu, I) table.

    Tables: ``interpolation="sqrt-poly"`` (default) represents the table by the
    least-squares polynomial in sqrt(mu) of the smallest degree (<= 12) whose
    largest residual at the table points is below ``rtol`` times max(I); it is
    exact for any Claret non-linear profile, smooth (so the exact engine
    converges spectrally), and the residual is kept in ``table_residual``.
    ``"linear"`` (the paper's scheme) and ``"cubic"`` (natural spline) pass
    through every point; they have kinks at the nodes, so the exact engine's
    error for them is larger (about 1e-9 at order 20 for a 40-point table;
    docs/exact.md, "Tables").

    The fields below are filled by the constructors; the class's own
    ``__init__`` takes them as keywords (an internal form).

    Attributes
    ----------
    law : str
        "uniform", "quadratic", "nonlinear", "power2" or "tabulated" (static).
    params : jax.Array
        The law's coefficients, [0] (uniform), [2] (u1, u2), [4] (c1..c4),
        [2] (c, alpha), or the table's intensities [n_nodes] (traceable:
        differentiate the flux with respect to them).
    mu_nodes : jax.Array or None
        The table's mu [n_nodes], from 0 to 1 (tables only).
    interpolation : str
        The table's interpolation, "sqrt-poly", "linear" or "cubic" ("" for
        a law; static).
    degree : int
        Degree of the "sqrt-poly" polynomial (0 otherwise; static).
    fit_matrix : jax.Array or None
        "sqrt-poly": the linear map from table intensities to the Chebyshev
        coefficients of I in x = 2 sqrt(mu) - 1, [degree + 1, n_nodes].
    q_matrix : jax.Array or None
        "sqrt-poly": the linear map from table intensities to the
        Chebyshev coefficients of the radial primitive that the exact engine
        integrates (``jaxppo.core.intensity.sqrt_cheb_operators``),
        [degree + 4, n_nodes].
    table_residual : float
        "sqrt-poly": the largest |fit - table| at the nodes (-1: unknown,
        traced intensities; 0 otherwise; static).
    surface : callable or None
        A surface map ``surface(x, y)`` (``with_surface``; static).
    spots : Spots or None
        Rotating spots (``with_spots``).

    See Also
    --------
    phoenix_star : a tabulated star from a PHOENIX model atmosphere.
    claret_quadratic : a quadratic law from Claret (2018).
    claret_power2 : a power-2 law from Claret & Southworth (2023).
    kepler20_star : the default Kepler-20-like star.

    Examples
    --------
    >>> import jaxppo as jp
    >>> star = jp.Star.quadratic(0.4, 0.25)
    >>> star
    Star.quadratic(0.4, 0.25)
    >>> print(f"I(mu=0.5) = {float(star.intensity(0.5)):.4f}, F0 = {float(star.total_flux):.6f}")
    I(mu=0.5) = 0.7375, F0 = 2.591814
    >>> f = jp.occultation_flux(star, x=0.0, y=0.0, r=0.1)  # a disk at the centre
    >>> print(f"{float(f):.6f}")
    0.987891
    """

    law: str = eqx.field(static=True)
    params: Array
    mu_nodes: Array | None = None
    interpolation: str = eqx.field(static=True, default="")
    degree: int = eqx.field(static=True, default=0)
    fit_matrix: Array | None = None
    q_matrix: Array | None = None
    table_residual: float = eqx.field(static=True, default=0.0)
    surface: object = eqx.field(static=True, default=None)
    spots: Spots | None = None

    # ---- constructors --------------------------------------------------------
    @classmethod
    def uniform(cls) -> "Star":
        """Build a star of uniform brightness, I = 1 (no limb darkening).

        Returns
        -------
        star : Star
            ``law="uniform"``; F0 = pi.

        Examples
        --------
        >>> import jaxppo as jp
        >>> print(f"{float(jp.Star.uniform().total_flux):.6f}")
        3.141593
        """
        return cls(law="uniform", params=jnp.zeros(0))

    @classmethod
    def quadratic(cls, u1: ArrayLike, u2: ArrayLike) -> "Star":
        """Build a quadratic-law star, I = 1 - u1 (1 - mu) - u2 (1 - mu)^2.

        F0 = pi (1 - u1 / 3 - u2 / 6). The coefficients may be traced
        (``jit``, ``grad``); then they are not checked.

        Parameters
        ----------
        u1 : array_like
            Linear coefficient (a scalar).
        u2 : array_like
            Quadratic coefficient (a scalar).

        Returns
        -------
        star : Star
            ``law="quadratic"``, ``params = [u1, u2]``.

        Raises
        ------
        ValueError
            When a concrete coefficient is not finite, or the total flux
            F0 <= 0.

        Warns
        -----
        UserWarning
            When I(mu) < 0 somewhere on [0, 1] (not a physical profile,
            though the engine integrates it exactly; concrete values only).

        Examples
        --------
        >>> import jaxppo as jp
        >>> star = jp.Star.quadratic(0.4, 0.25)
        >>> print(f"{float(star.intensity(0.0)):.4f} {float(star.total_flux):.6f}")
        0.3500 2.591814
        """
        _check_coefficient("u1", u1)
        _check_coefficient("u2", u2)
        star = cls(law="quadratic", params=jnp.stack([jnp.asarray(u1, float), jnp.asarray(u2, float)]))
        return _check_profile(star, f"u1={_plain(u1)}, u2={_plain(u2)}")

    @classmethod
    def nonlinear(cls, c1: ArrayLike, c2: ArrayLike, c3: ArrayLike, c4: ArrayLike) -> "Star":
        """Build a non-linear-law star (Claret 2000).

        I = 1 - sum_k c_k (1 - mu^(k/2)), k = 1..4. The coefficients may be
        traced (``jit``, ``grad``); then they are not checked.

        Parameters
        ----------
        c1, c2, c3, c4 : array_like
            The coefficients of mu^(1/2), mu, mu^(3/2), mu^2 (scalars).

        Returns
        -------
        star : Star
            ``law="nonlinear"``, ``params = [c1, c2, c3, c4]``.

        Raises
        ------
        ValueError
            When a concrete coefficient is not finite, or the total flux
            F0 <= 0.

        Warns
        -----
        UserWarning
            When I(mu) < 0 somewhere on [0, 1] (not a physical profile,
            though the engine integrates it exactly; concrete values only).

        Examples
        --------
        >>> import jaxppo as jp
        >>> star = jp.Star.nonlinear(0.6, -0.2, 0.5, -0.2)
        >>> print(f"{float(star.intensity(0.0)):.4f} {float(star.total_flux):.6f}")
        0.3000 2.615002
        """
        for name, v in zip(("c1", "c2", "c3", "c4"), (c1, c2, c3, c4)):
            _check_coefficient(name, v)
        star = cls(law="nonlinear", params=jnp.stack([jnp.asarray(v, float) for v in (c1, c2, c3, c4)]))
        return _check_profile(star, f"c1={_plain(c1)}, c2={_plain(c2)}, c3={_plain(c3)}, c4={_plain(c4)}")

    @classmethod
    def power2(cls, c: ArrayLike, alpha: ArrayLike) -> "Star":
        """Build a power-2 law star, I = 1 - c (1 - mu^alpha).

        Hestroffer (1997); Claret & Southworth (2023) tabulate c as ``g``
        and alpha as ``h`` (``claret_power2``). The coefficients may be
        traced (``jit``, ``grad``); then they are not checked.

        Parameters
        ----------
        c : array_like
            Strength of the darkening (a scalar).
        alpha : array_like
            Exponent, > 0 (a scalar).

        Returns
        -------
        star : Star
            ``law="power2"``, ``params = [c, alpha]``.

        Raises
        ------
        ValueError
            When a concrete coefficient is not finite, alpha <= 0, or the
            total flux F0 <= 0.

        Warns
        -----
        UserWarning
            When I(mu) < 0 somewhere on [0, 1] (not a physical profile,
            though the engine integrates it exactly; concrete values only).

        Examples
        --------
        >>> import jaxppo as jp
        >>> star = jp.Star.power2(0.6, 0.6)
        >>> print(f"{float(star.intensity(0.0)):.4f} {float(star.total_flux):.6f}")
        0.4000 2.706603
        """
        _check_coefficient("c", c)
        _check_finite("alpha", alpha)
        # any concrete value (Python or numpy scalar, 0-d array) is checked
        if not _is_traced(alpha) and np.any(np.asarray(alpha, dtype=float) <= 0):
            raise ValueError(f"power-2 exponent alpha must be > 0, got {alpha!r}")
        _check_coefficient("alpha", alpha)
        star = cls(law="power2", params=jnp.stack([jnp.asarray(c, float), jnp.asarray(alpha, float)]))
        return _check_profile(star, f"c={_plain(c)}, alpha={_plain(alpha)}")

    @classmethod
    def tabulated(
        cls,
        mu: ArrayLike,
        intensity: ArrayLike,
        interpolation: str = "sqrt-poly",
        max_degree: int = 12,
        rtol: float = 1e-6,
        degree: int | None = None,
        pad_ends: bool = False,
    ) -> "Star":
        """Build a star from a table of specific intensities I(mu).

        ``mu`` must be strictly increasing in [0, 1] (at least 3 points) and the
        intensities finite and >= 0. The table must reach mu = 0 and mu = 1:
        the flux integrates I over the whole disk, and outside the table the
        interpolation would invent the limb (a 3-node sqrt-poly table from
        mu = 0.2 gave I(0.05) = 0.18 and I(0) = 0.3 for I(0.2) = 0.3). A
        table that stops short raises ValueError unless ``pad_ends=True``,
        which adds a node at mu = 0 (and 1) repeating the nearest intensity;
        the profile is then flat beyond the table only with
        ``interpolation="linear"`` ("sqrt-poly" and "cubic" curve between the
        added node and the table). PHOENIX tables (``phoenix_star``)
        reach both ends.

        ``degree`` fixes the degree of the "sqrt-poly" fit (default: the
        smallest that meets ``rtol``, chosen from the values). The
        intensities may be traced (``jax.grad`` with respect to the table,
        ``jit``): then ``mu`` must be concrete, the values are not checked,
        "sqrt-poly" needs ``degree`` (the adaptive choice needs the values;
        take it from the concrete table, ``Star.tabulated(mu, I0).degree``)
        and ``table_residual`` is -1 (unknown).

        Parameters
        ----------
        mu : array_like
            The nodes, strictly increasing in [0, 1], [n_nodes] (concrete).
        intensity : array_like
            I at each node, >= 0, not all zero, [n_nodes] (any scale; the
            flux is normalised by F0). May be traced.
        interpolation : {"sqrt-poly", "linear", "cubic"}, optional
            The representation between nodes (default "sqrt-poly").
        max_degree : int, optional
            "sqrt-poly": the largest degree the adaptive choice tries
            (default 12; it warns and smooths when none meets ``rtol``).
        rtol : float, optional
            "sqrt-poly": the largest residual at the nodes, relative to
            max(I), that the adaptive choice accepts (default 1e-6).
        degree : int, optional
            "sqrt-poly": a fixed degree, from 1 to n_nodes - 1 (default None:
            the adaptive choice).
        pad_ends : bool, optional
            Repeat the end intensities at mu = 0 and 1 when the table stops
            short of them (default False: such a table raises).

        Returns
        -------
        star : Star
            ``law="tabulated"``.

        Raises
        ------
        ValueError
            When ``interpolation`` is unknown; ``mu`` is traced, has fewer
            than 3 points, is not finite, leaves [0, 1], is not strictly
            increasing, or stops short of 0 or 1 without ``pad_ends``; ``mu``
            and ``intensity`` are not 1D of equal length; ``degree`` is not
            an integer from 1 to n_nodes - 1; concrete intensities are not
            finite, negative somewhere or zero everywhere; or "sqrt-poly"
            has traced intensities and no ``degree``.

        Warns
        -----
        UserWarning
            When no "sqrt-poly" degree <= ``max_degree`` meets ``rtol`` (the
            table is smoothed).

        Examples
        --------
        A quadratic law as a table: "sqrt-poly" represents it exactly (mu is
        a polynomial in sqrt(mu)), "linear" misses F0 by its kinks.

        >>> import numpy as np
        >>> import jaxppo as jp
        >>> mu = np.linspace(0.0, 1.0, 11)
        >>> inten = 1.0 - 0.4 * (1.0 - mu) - 0.25 * (1.0 - mu) ** 2
        >>> star = jp.Star.tabulated(mu, inten)
        >>> star.degree
        4
        >>> print(f"{float(star.total_flux):.6f}")
        2.591814
        >>> print(f"{float(jp.Star.tabulated(mu, inten, interpolation='linear').total_flux):.6f}")
        2.590505
        """
        if interpolation not in _INTERPOLATIONS:
            raise ValueError(
                f"interpolation must be one of {_INTERPOLATIONS}, got {interpolation!r}"
            )
        if _is_traced(mu):
            raise ValueError("mu (the table's nodes) must be concrete; only the intensities may be traced")
        traced = _is_traced(intensity)
        mu_np = np.asarray(mu, dtype=float)
        i_in = jnp.asarray(intensity) if traced else np.asarray(intensity, dtype=float)
        if mu_np.ndim != 1 or i_in.shape != mu_np.shape:
            raise ValueError(
                f"mu and intensity must be 1D of equal length, got shapes {mu_np.shape} and {i_in.shape}"
            )
        _check_mu_nodes(mu_np, pad_ends)
        if degree is not None and (
            isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or not 1 <= degree < mu_np.size
        ):
            raise ValueError(f"degree must be an integer from 1 to {mu_np.size - 1} (points - 1), got {degree!r}")
        if not traced:
            _check_finite("intensity", i_in)
            if np.any(i_in < 0):
                raise ValueError(f"intensity must be >= 0, got minimum {i_in.min()}")
            if np.max(i_in) <= 0:
                raise ValueError("intensity must not be zero everywhere")
        xp = jnp if traced else np
        if mu_np[0] > 0:
            mu_np, i_in = np.concatenate([[0.0], mu_np]), xp.concatenate([i_in[:1], i_in])
        if mu_np[-1] < 1:
            mu_np, i_in = np.concatenate([mu_np, [1.0]]), xp.concatenate([i_in, i_in[-1:]])
        if interpolation == "sqrt-poly":
            if degree is None:
                if traced:
                    raise ValueError(
                        "interpolation='sqrt-poly' with traced intensities needs degree= (the adaptive "
                        "choice needs concrete values; use Star.tabulated(mu, I0).degree of your table)"
                    )
                degree = _choose_degree(mu_np, i_in, max_degree, rtol)
            fit, qmap = _I.sqrt_cheb_operators(mu_np, degree)
            resid = -1.0 if traced else float(np.max(np.abs(_sqrt_poly_design(mu_np, degree) @ (fit @ i_in) - i_in)))
            return cls(
                law="tabulated", params=jnp.asarray(i_in), mu_nodes=jnp.asarray(mu_np),
                interpolation=interpolation, degree=degree, fit_matrix=jnp.asarray(fit),
                q_matrix=jnp.asarray(qmap), table_residual=resid,
            )
        return cls(
            law="tabulated", params=jnp.asarray(i_in), mu_nodes=jnp.asarray(mu_np),
            interpolation=interpolation,
        )

    @classmethod
    def from_law(cls, law: str, coefficients=()) -> "Star":
        """Build a star from a law name and its coefficients (used by configs).

        Parameters
        ----------
        law : str
            "uniform", "quadratic", "nonlinear" or "power2" (any case).
        coefficients : array_like, optional
            The law's coefficients, in the order of its constructor: none,
            (u1, u2), (c1, c2, c3, c4) or (c, alpha).

        Returns
        -------
        star : Star
            ``Star.<law>(*coefficients)``.

        Raises
        ------
        ValueError
            When the law is unknown (tables: ``tabulated``) or the number
            of coefficients is not the law's; and as the law's constructor.

        Examples
        --------
        >>> import jaxppo as jp
        >>> jp.Star.from_law("quadratic", [0.4, 0.25])
        Star.quadratic(0.4, 0.25)
        """
        law = str(law).lower()
        if hasattr(coefficients, "unit"):
            _check_finite("coefficients", coefficients)  # a Quantity array is refused as a whole
        given = np.atleast_1d(np.asarray(coefficients, dtype=object))
        for k, v in enumerate(given):
            _check_finite(f"coefficients[{k}]", v)  # a quoted number or a bool is refused by name
        coefficients = [float(v) for v in np.asarray(given, dtype=float)] if given.size else []  # plain floats print plainly
        need = {"uniform": 0, "quadratic": 2, "nonlinear": 4, "power2": 2}
        if law not in need:
            raise ValueError(f"unknown limb-darkening law {law!r}; expected one of {tuple(need)} (tables: Star.tabulated)")
        if len(coefficients) != need[law]:
            raise ValueError(f"law {law!r} needs {need[law]} coefficients, got {len(coefficients)}: {coefficients}")
        return getattr(cls, law)(*coefficients)

    # ---- the profile in power-basis / table form ------------------------------
    def _halfint(self) -> tuple[Array, tuple[int, ...]] | None:
        """(a_k, 2 e_k) when I = sum_k a_k mu**e_k with half-integer e_k."""
        p = self.params
        if self.law == "uniform":
            return jnp.ones(1, self.params.dtype), (0,)
        if self.law == "quadratic":
            u1, u2 = p[0], p[1]
            return jnp.stack([1.0 - u1 - u2, u1 + 2.0 * u2, -u2]), (0, 2, 4)
        if self.law == "nonlinear":
            return jnp.concatenate([jnp.reshape(1.0 - jnp.sum(p), (1,)), p]), (0, 1, 2, 3, 4)
        return None

    def _power(self) -> tuple[Array, Array]:
        c, alpha = self.params[0], self.params[1]
        return jnp.stack([1.0 - c, c]), jnp.stack([jnp.zeros_like(alpha), alpha])

    def _table(self) -> tuple[Array, Array, Array]:
        b = _I.spline_coefficients(self.mu_nodes, self.params, self.interpolation)
        return self.mu_nodes, b, _I.table_cumulative(self.mu_nodes, b)

    # ---- what the kernels need ----------------------------------------------
    def intensity(self, mu: ArrayLike) -> Array:
        """Evaluate the specific intensity I(mu).

        Relative to the law's centre (1 at mu = 1) or in the table's units;
        not normalised: divide by ``total_flux`` for intensity per unit flux.

        Parameters
        ----------
        mu : array_like
            mu = sqrt(1 - r^2) in [0, 1], any shape.

        Returns
        -------
        intensity : jax.Array
            I(mu), the shape of ``mu``.

        Examples
        --------
        >>> import numpy as np
        >>> import jaxppo as jp
        >>> star = jp.Star.quadratic(0.4, 0.25)
        >>> print(np.asarray(star.intensity(np.array([0.0, 0.5, 1.0]))))
        [0.35   0.7375 1.    ]
        """
        half = self._halfint()
        if half is not None:
            a, twice_e = half
            return _I.power_basis_intensity(mu, a, jnp.asarray(twice_e, float) / 2.0)
        if self.law == "power2":
            return _I.power_basis_intensity(mu, *self._power())
        if self.interpolation == "sqrt-poly":
            m = jnp.clip(jnp.asarray(mu), 0.0, 1.0)
            return _I.cheb_eval(2.0 * jnp.sqrt(m) - 1.0, self.fit_matrix @ self.params)
        mu_nodes, b, _ = self._table()
        return _I.table_intensity(mu, mu_nodes, b)

    def radial_kernel(self):
        """Return the radial kernel that the exact engine integrates.

        Phi(r) = int_0^r s I(s) ds = int_mu^1 m I(m) dm is the radial
        primitive of the profile (``jaxppo.core.intensity``); by Green's
        theorem the flux inside a region is the contour integral of
        g(r^2) (x dy - y dx), with g(s) = Phi(sqrt(s)) / s.

        Returns
        -------
        g : callable
            s -> g(s) for s = r^2 in [0, 1] (jnp-traceable; g(0) = I(1) / 2).
        phi1 : jax.Array
            Phi(1) = F0 / (2 pi).

        Examples
        --------
        >>> import jaxppo as jp
        >>> g, phi1 = jp.Star.quadratic(0.4, 0.25).radial_kernel()
        >>> print(f"{float(g(0.0)):.4f} {float(phi1):.4f}")
        0.5000 0.4125
        """
        half = self._halfint()
        if half is not None:
            a, twice_e = half
            coef = _I.halfint_coefficients(a, twice_e)
            phi1 = jnp.sum(a * jnp.asarray([2.0 / (te + 4.0) for te in twice_e], dtype=a.dtype))
            return (lambda s: _I.halfint_g(s, coef)), phi1
        if self.law == "power2":
            a, e = self._power()
            return (lambda s: _I.power_basis_g(s, a, e)), _I.power_basis_total(a, e) / (2 * jnp.pi)
        if self.interpolation == "sqrt-poly":
            qc = self.q_matrix @ self.params
            return (lambda s: _I.cheb_g(s, qc)), _I.cheb_g(jnp.ones((), qc.dtype), qc)
        mu_nodes, b, phin = self._table()
        return (lambda s: _I.table_g(s, mu_nodes, b, phin)), phin[0]

    def radial_intensity(self):
        """Return the intensity as a function of s = r^2.

        What the exact engine's derivatives integrate along the disks' arcs.

        Returns
        -------
        intensity : callable
            s -> I(mu) at s = r^2 = 1 - mu^2 (s clipped to [0, 1];
            jnp-traceable).

        Examples
        --------
        >>> import jaxppo as jp
        >>> radial = jp.Star.quadratic(0.4, 0.25).radial_intensity()
        >>> print(f"{float(radial(0.75)):.4f}")  # r^2 = 0.75: mu = 0.5
        0.7375
        """

        half = self._halfint()
        if half is not None:
            # a polynomial in v = mu^(1/2): no power per term and node
            a, twice_e = half
            coef = [0.0] * (max(twice_e) + 1)
            for ak, te in zip(a, twice_e):
                coef[te] = coef[te] + ak

            return lambda s: _I.halfint_poly(s, coef)

        def intensity(s):
            m2 = 1.0 - jnp.asarray(s)
            inside = m2 > 0
            return self.intensity(jnp.where(inside, jnp.sqrt(jnp.where(inside, m2, 1.0)), 0.0))

        return intensity

    @property
    def total_flux(self) -> Array:
        """Total flux F0 = 2 pi int_0^1 I(mu) mu dmu, exact (a closed form).

        A 0-d ``jax.Array`` (differentiable in the star's parameters); pi for
        a uniform star.
        """
        return 2.0 * jnp.pi * self.radial_kernel()[1]

    @property
    def smooth(self) -> bool:
        """I(mu) analytic on the open disk (every law, and sqrt-poly tables);
        False for piecewise "linear" and "cubic" tables, whose kinks the fast
        quadrature rules of ``"auto"`` would not resolve."""
        return not (self.law == "tabulated" and self.interpolation in ("linear", "cubic"))

    @property
    def symmetric(self) -> bool:
        """Radially symmetric (no surface map, no spots)."""
        return self.surface is None and self.spots is None

    def with_surface(self, surface) -> "Star":
        """Return this star times a surface map.

        Such a star is not radially symmetric: only ``method="raster"`` can
        model it, and ``"auto"`` uses the raster for it (its flux is relative
        to the mapped star's own unocculted flux).

        Parameters
        ----------
        surface : callable
            ``surface(x, y)`` in sky coordinates [R*], a jnp-traceable
            function of arrays, multiplying I (spots, faculae).

        Returns
        -------
        star : Star
            A copy with ``surface`` set (``symmetric`` is False).

        Raises
        ------
        ValueError
            When ``surface`` is not callable.

        Examples
        --------
        >>> import jax.numpy as jnp
        >>> import jaxppo as jp
        >>> star = jp.Star.uniform().with_surface(lambda x, y: jnp.where(x > 0.5, 0.5, 1.0))
        >>> star.symmetric
        False
        """
        if not callable(surface):
            raise ValueError(f"surface must be a function surface(x, y), got {type(surface).__name__}")
        return dataclasses.replace(self, surface=surface)

    def with_spots(self, spots: Spots | None = None, **kwargs) -> "Star":
        """Return this star with rotating circular spots.

        The surface depends on time, so the flux needs the time of every
        frame: ``System.flux`` passes its t (``occultation_flux`` and
        ``raster_flux`` take ``times=``). Only the raster models it; the flux
        is relative to the unspotted star's total flux F0 (docs/activity.md).

        Parameters
        ----------
        spots : Spots, optional
            The spots; or None, and give their arguments as keywords.
        **kwargs
            The arguments of ``Spots`` (``lat``, ``lon``, ``radius``,
            ``contrast``, ``period``, ``inc``, ``t_ref``, ``obliquity``,
            ``edge``), when ``spots`` is None.

        Returns
        -------
        star : Star
            A copy with ``spots`` set (``symmetric`` is False).

        Raises
        ------
        ValueError
            When both ``spots`` and keywords are given, ``spots`` is not a
            ``Spots``, or (from ``Spots``) the keywords are invalid.

        Examples
        --------
        >>> import jaxppo as jp
        >>> star = jp.Star.quadratic(0.4, 0.25).with_spots(lat=20.0, lon=0.0, radius=10.0, contrast=0.5, period=10.0)
        >>> star.spots.n, star.symmetric
        (1, False)
        """
        if spots is None:
            spots = Spots(**kwargs)
        elif kwargs:
            raise ValueError(f"pass either a Spots or its arguments, not both (got {sorted(kwargs)})")
        if not isinstance(spots, Spots):
            raise ValueError(f"spots must be a jaxppo Spots, got {type(spots).__name__}")
        return dataclasses.replace(self, spots=spots)

    def __repr__(self) -> str:
        if self.law == "tabulated":
            extra = f", degree={self.degree}, residual={self.table_residual:.2e}" if self.interpolation == "sqrt-poly" else ""
            return f"Star.tabulated({len(self.mu_nodes)} points, interpolation={self.interpolation!r}{extra})"
        return f"Star.{self.law}({', '.join(f'{float(v):.6g}' for v in np.asarray(self.params))})"
