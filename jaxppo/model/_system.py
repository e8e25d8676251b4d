"""Planets on circular or eccentric orbits, the tilt alpha of one orbit and
the hemisphere cases (multi-transits: ``jaxppo.model._transits``).

Frame and equations: docs/conventions.md (sky frame x right, y up, z to the
observer; Mueller et al. 2021, Sect. 2.5 and Eqs. 2-6; eccentric orbits as
in Winn 2010).
"""

from __future__ import annotations

import os
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._flux import occultation_flux
from ..core.geometry import orbit_position
from ._contacts import eccentric_contacts
from ._star import Star
from ._ttv import check_transit_times, epochs_text, mid_time, shifted_time
from ._units import from_quantity

__all__ = ["scan_cases", "require_keplerian", "Planet", "System", "CASES", "hemisphere_cases", "case_label", "case_signs"]

# Named hemisphere cases: every untilted planet in the tilted planet's
# hemisphere ("same", paper case 1) or every one in the other ("opposite",
# paper case 4). Systems of k planets have 2^(k-1) distinct configurations,
# given as a tuple of +-1 signs (one per untilted planet, in planet order).
CASES = ("same", "opposite")


def case_signs(n_planets: int, tilted: int, case) -> np.ndarray:
    """Hemisphere sign of every planet [n_planets] for ``case``: +1 for the
    tilted planet and for untilted planets on its side of the stellar equator,
    -1 for the mirrored ones.

    ``case``: "same" (all +1), "opposite" (all -1), a tuple of +-1 (one per
    untilted planet, in planet order), or a string of "+"/"-" of that length
    (as written by ``case_label``).
    """
    k = n_planets - 1
    if isinstance(case, str):
        if case == "same":
            rel = (1,) * k
        elif case == "opposite":
            rel = (-1,) * k
        elif case and set(case) <= {"+", "-"}:
            rel = tuple(1 if ch == "+" else -1 for ch in case)
        else:
            raise ValueError(
                f"unknown case {case!r}: case must be one of {CASES}, a tuple of +-1 or a '+'/'-' string "
                "(one per untilted planet)"
            )
    else:
        try:
            rel = tuple(case)
        except TypeError:
            raise ValueError(f"case must be one of {CASES} or a tuple of +-1, got {case!r}") from None
        if not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)) and v in (1, -1) for v in rel):
            raise ValueError(f"case signs must each be +1 or -1, got {case!r}")
    if len(rel) != k:
        raise ValueError(f"case must give {k} sign(s) (one per untilted planet), got {case!r}")
    signs = list(rel)
    signs.insert(tilted, 1)
    return np.asarray(signs, float)


def case_label(case) -> str:
    """Name a hemisphere case as text.

    Uniform sign tuples become "same" (all +1) or "opposite" (all -1); mixed
    ones become a string of "+"/"-" (one character per untilted planet, in
    planet order). The text is safe in CSV files, and
    ``jaxppo.model._system.case_signs`` reads it back.

    Parameters
    ----------
    case : str or tuple of int
        A case as ``hemisphere_cases`` gives it: "same", "opposite"
        (returned unchanged, as is any string), or a tuple of +1/-1 signs of
        the untilted planets relative to the tilted one.

    Returns
    -------
    label : str
        "same", "opposite" or the "+"/"-" string.

    See Also
    --------
    hemisphere_cases : the distinct cases of a system.

    Examples
    --------
    >>> import jaxppo as jp
    >>> jp.case_label((1, -1))
    '+-'
    >>> jp.case_label((1, 1)), jp.case_label((-1, -1)), jp.case_label("same")
    ('same', 'opposite', 'same')
    """
    if isinstance(case, str):
        return case
    rel = tuple(int(v) for v in case)
    if all(v == 1 for v in rel):
        return "same"
    if all(v == -1 for v in rel):
        return "opposite"
    return "".join("+" if v == 1 else "-" for v in rel)


def scan_cases(system: "System", cases) -> tuple[str, ...]:
    """The hemisphere cases of a scan as text labels (``case_label``):
    ``"all"`` gives every configuration that differs (``hemisphere_cases``),
    otherwise a non-empty list of "same", "opposite" or "+"/"-" strings (one
    sign per untilted planet). Raises ValueError naming the bad entry."""
    if isinstance(cases, str):
        if cases != "all":
            cases = [cases]
        else:
            return tuple(case_label(c) for c in hemisphere_cases(system))
    cases = list(cases)
    if not cases:
        raise ValueError("cases must not be empty")
    if len(system.planets) < 2:
        raise ValueError(f"an obliquity scan needs two or more planets (one is tilted against the others); this "
                         f"system has one ({system.planets[0].name or 0!r})")
    out = []
    for c in cases:
        if not isinstance(c, str):
            raise ValueError(f"each case must be a string ('same', 'opposite', or '+'/'-' signs), got {c!r}")
        signs = case_signs(len(system.planets), system.tilted, c)  # raises with the reason
        # canonical label: "+" of a two-planet system is "same", "-+" stays "-+"
        label = case_label(tuple(int(v) for i, v in enumerate(signs) if i != system.tilted))
        if label in out:
            raise ValueError(f"case {c!r} is listed twice (it is the configuration {label!r} of this system, "
                             f"given as {[x for x in cases if x != c] or [c]})")
        out.append(label)
    return tuple(out)


def hemisphere_cases(system: "System") -> tuple:
    """List the hemisphere configurations of a system that give different light curves.

    A k-planet system has 2^(k-1) of them: each untilted planet crosses the
    stellar disk either in the tilted planet's hemisphere (+1) or in the
    other one (-1). Only the untilted planets' signs relative to the tilted
    planet matter: a mirror y -> -y of the whole sky maps any configuration
    at alpha to its mirror image at 360 - alpha, and a radially symmetric
    star gives both the same flux, so a full alpha scan covers both signs of
    the tilted planet.

    Parameters
    ----------
    system : System
        The star and planets; ``system.tilted`` is the tilted planet.

    Returns
    -------
    cases : tuple
        "same" first (every untilted planet in the tilted planet's
        hemisphere, paper case 1) and "opposite" last (every one in the
        other, paper case 4); the mixed ones in between as tuples of +1/-1
        (one per untilted planet, in planet order). A single-planet system
        gives ``("same",)``. Each is a valid ``case`` of ``System.flux``;
        ``case_label`` names them as text.

    Examples
    --------
    >>> import jaxppo as jp
    >>> jp.hemisphere_cases(jp.kepler20_system())
    ('same', 'opposite')
    >>> planets = [jp.Planet(3.0 * k, 0.0, 10.0 * k, 89.5, 0.02, name=n) for k, n in ((1, "b"), (2, "c"), (3, "d"))]
    >>> jp.hemisphere_cases(jp.System(jp.Star.uniform(), planets))
    ('same', (1, -1), (-1, 1), 'opposite')
    """
    k = len(system.planets) - 1
    if k == 0:
        return ("same",)
    out = []
    for bits in range(2**k):
        rel = tuple(-1 if (bits >> (k - 1 - j)) & 1 else 1 for j in range(k))
        out.append(case_label(rel) if len(set(rel)) == 1 else rel)
    return tuple(out)


def _positive(name: str, value, *, strict=True, lower=0.0) -> None:
    if isinstance(value, jax.core.Tracer):
        return
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    bad = arr <= lower if strict else arr < lower
    if np.any(bad):
        op = ">" if strict else ">="
        raise ValueError(f"{name} must be {op} {lower}, got {value!r}")


def require_keplerian(system, what: str) -> None:
    """Refuse an N-body system or one whose planets have moons in a
    workflow that assumes planets on their own Keplerian orbits (its
    windows, masks or angle limits come from each planet's ephemeris and
    contacts), naming the workflow: a clear error, never a linear
    ephemeris or a moon left out in silence."""
    if system.orbits == "nbody":
        raise ValueError(f"{what} assumes planets on Keplerian orbits (with transit times, if listed); this system "
                         "has N-body orbits (orbits='nbody'): fit it with jp.fit / jp.sample, or give its transit "
                         "times (system.transit_times) to the Keplerian planets (Planet(..., transit_times=))")
    if any(pl.moons for pl in system.planets):
        raise ValueError(f"{what} does not model moons yet (its transit windows and masks would leave them out); "
                         "fit a system with moons with jp.fit / jp.sample")


def user_stacklevel() -> int:
    """The ``stacklevel`` that points a warning at the first frame outside
    jaxppo and equinox (a Planet's checks run inside equinox's module
    machinery, so a fixed level pointed into equinox)."""
    import inspect

    level, frame = 1, inspect.currentframe()
    inside = ("jaxppo" + os.sep, "equinox" + os.sep)
    while frame is not None:
        name = frame.f_code.co_filename
        if level > 1 and not any(part in name for part in inside) and not name.startswith("<frozen"):
            return level - 1
        frame, level = frame.f_back, level + 1
    return 2


class Planet(eqx.Module):
    """A planet on a Keplerian orbit (circular by default).

    An equinox module (a JAX pytree): its numeric fields can be traced,
    fitted and differentiated; ``name`` and ``transit_epochs`` are static.
    astropy Quantities are converted (inc, omega: any angle unit; period,
    t0: any time unit; a, radius, e: dimensionless, e.g.
    ``(a / R_star).decompose()``; a bare length is refused as ambiguous).
    Plain numbers mean deg and days. Frame and orbit equations:
    docs/conventions.md (Mueller et al. 2021, Sect. 2.5; eccentric orbits as
    in Winn 2010).

    Parameters
    ----------
    period : float or Quantity
        Orbital period P [d], > 0.
    t0 : float or Quantity
        A time of conjunction = mid-transit [d] (any consistent zero point,
        e.g. BKJD = BJD - 2454833), also for eccentric orbits.
    a : float or Quantity or None
        Semi-major axis [R*], > 1. None only for a planet of an N-body
        ``System`` (``orbits="nbody"``), which derives it from the period and
        the masses (Kepler's third law).
    inc : float or Quantity
        Inclination i [deg] in [0, 180]; the impact parameter is
        b = a cos(i) (1 - e^2) / (1 + e sin omega).
    radius : float or Quantity
        Radius ratio p = R_p / R* [R*], > 0.
    name : str, optional
        Label used in free-parameter names ("b.t0") and in tables; default "".
    e : float or Quantity, optional
        Eccentricity, 0 <= e < 1 (default 0, circular); the periastron
        distance a (1 - e) must exceed 1 + radius (else the planet would hit
        the star).
    omega : float or Quantity, optional
        Argument of periastron [deg], as in Winn (2010), batman (``w``) and
        jaxoplanet: omega = 90 deg (default) puts periastron at transit,
        270 deg apoastron. Unused when e = 0.
    transit_times : array_like or None, optional
        Measured (or free) mid-times [d] of the epochs in ``transit_epochs``
        [n_listed], each within half a period of t0 + n P. The orbit is then
        shifted, at every time, by the offset tc_n - t0 - n P of the listed
        transit nearest in time (docs/conventions.md, "Transit times").
        None (default): the linear ephemeris t0 + n P.
    transit_epochs : sequence of int or None, optional
        Integer epochs of ``transit_times`` (static; default 0..n-1; epoch 0
        is the transit at t0).
    lnode : float or Quantity, optional
        Longitude of the ascending node Omega [deg] (default 0): the orbit
        rotated about the line of sight, x' = x cos Omega + y sin Omega,
        y' = -x sin Omega + y cos Omega, the rotation of the tilt alpha
        (docs/conventions.md). The tilted planet of a System is rotated by
        Omega + alpha.
    mass : float or Quantity, optional
        Planet mass [M_sun], >= 0 (default 0); used by N-body orbits only
        (``System(..., orbits="nbody")``).
    moons : sequence of Moon, optional
        The planet's moons (default none): the orbit above is then that of
        the planet-moon barycentre, each moon on its Keplerian orbit about
        the planet and the planet recoiling from them (``jaxppo.Moon``;
        docs/conventions.md, "Moons"). ``System`` adds their disks after
        the planets'.

    Attributes
    ----------
    period, t0, a, inc, radius, e, omega, lnode, mass : jax.Array
        The orbit, as float arrays in the units above (a is NaN when not
        given).
    moons : tuple of Moon
        The moons.
    name : str
        The label.
    transit_times : jax.Array or None
        The listed mid-times [d], shape [n_listed], or None.
    transit_epochs : tuple of int or None
        Their epochs, or None.

    Raises
    ------
    ValueError
        When a concrete parameter is out of range or not finite: period <= 0,
        a <= 1, radius <= 0, inc outside [0, 180] deg, e outside [0, 1),
        periastron a (1 - e) <= 1 + radius, a non-finite t0 or omega; a
        Quantity of the wrong kind (e.g. a length for ``a``, an absolute
        astropy ``Time`` for ``t0``); ``transit_times`` that are not a finite
        1D list, whose count differs from ``transit_epochs``, with repeated
        epochs, or a time more than half a period from t0 + n P.

    Warns
    -----
    UserWarning
        When the orbit can never transit (|b| >= 1 + radius and no contact):
        ``inc=1.53`` given in radians by habit means 1.53 deg, b ~ a.

    See Also
    --------
    System : a star with its planets, and their flux.

    Examples
    --------
    Kepler-20 b (Mueller et al. 2021, Table 3):

    >>> import jaxppo as jp
    >>> b = jp.Planet(period=3.6961159, t0=134.501962, a=10.60, inc=87.687, radius=0.01805, name="b")
    >>> print(f"b = {float(b.impact):.4f}, T14 = {2 * 24 * float(b.half_duration()):.3f} h")
    b = 0.4278, T14 = 2.466 h
    >>> print(f"{b.mid_time(3):.6f}")
    145.590310
    >>> x, y, z = b.position(134.501962)  # at mid-transit: x = 0, y = b, z > 0 (in front)
    >>> print(f"{float(x):.4f} {float(y):.4f} {float(z):.4f}")
    0.0000 0.4278 10.5914

    An eccentric orbit, whose transit is not symmetric about conjunction:

    >>> p = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.0, radius=0.03, e=0.3, omega=30.0)
    >>> t1, t4 = p.contacts()
    >>> print(f"{24 * float(t1):.3f} h, {24 * float(t4):.3f} h")
    -1.575 h, 1.571 h
    """

    period: Array
    t0: Array
    a: Array
    inc: Array
    radius: Array
    e: Array
    omega: Array
    lnode: Array
    mass: Array
    name: str = eqx.field(static=True, default="")
    transit_times: Array | None = None
    transit_epochs: tuple[int, ...] | None = eqx.field(static=True, default=None)
    moons: tuple = ()

    def __init__(self, period, t0, a, inc, radius, name: str = "", e=0.0, omega=90.0, transit_times=None,
                 transit_epochs=None, lnode=0.0, mass=0.0, moons=()):
        period = from_quantity("period", period, "d")
        t0 = from_quantity("t0", t0, "d")
        no_a = a is None
        a = np.nan if no_a else from_quantity("a", a, "")
        inc = from_quantity("inc", inc, "deg")
        radius = from_quantity("radius", radius, "")
        e = from_quantity("e", e, "")
        omega = from_quantity("omega", omega, "deg")
        _positive("period", period)
        _positive("t0", t0, strict=False, lower=-np.inf)
        if not no_a:
            _positive("a", a, lower=1.0)
        _positive("radius", radius)
        _positive("omega", omega, strict=False, lower=-np.inf)
        lnode = from_quantity("lnode", lnode, "deg")
        mass = from_quantity("mass", mass, "M_sun")
        _positive("lnode", lnode, strict=False, lower=-np.inf)
        _positive("mass", mass, strict=False)
        if not isinstance(inc, jax.core.Tracer):
            inc_arr = np.asarray(inc, dtype=float)
            if not np.all(np.isfinite(inc_arr)) or np.any((inc_arr < 0) | (inc_arr > 180)):
                raise ValueError(f"inc must be in [0, 180] degrees, got {inc!r}")
        if not isinstance(e, jax.core.Tracer):
            e_arr = np.asarray(e, dtype=float)
            if not np.all(np.isfinite(e_arr)) or np.any((e_arr < 0) | (e_arr >= 1)):
                raise ValueError(f"e (eccentricity) must be in [0, 1), got {e!r}")
            if not no_a and not any(isinstance(v, jax.core.Tracer) for v in (a, radius)):
                peri = np.asarray(a, float) * (1.0 - e_arr)
                if np.any(peri <= 1.0 + np.asarray(radius, float)):
                    raise ValueError(
                        f"planet {str(name)!r}: e = {e!r} puts periastron at a (1 - e) = {np.min(peri):.4g} R* <= "
                        f"1 + radius = {1.0 + np.max(np.asarray(radius, float)):.4g} R*, so the planet would hit the star"
                    )
        self.period = jnp.asarray(period, float)
        self.t0 = jnp.asarray(t0, float)
        self.a = jnp.asarray(a, float)
        self.inc = jnp.asarray(inc, float)
        self.radius = jnp.asarray(radius, float)
        self.e = jnp.asarray(e, float)
        self.omega = jnp.asarray(omega, float)
        self.lnode = jnp.asarray(lnode, float)
        self.mass = jnp.asarray(mass, float)
        self.name = str(name)
        if moons:
            from ._moon import check_moons  # _moon builds on Planet

            moons = check_moons(radius, moons)
        self.moons = tuple(moons)
        # ---- transit times (TTVs): checked and stored apart from the orbit
        if transit_times is not None and not isinstance(transit_times, (list, tuple, np.ndarray)):
            # a Quantity or TimeDelta in days; lists and arrays are checked below, naming what is wrong
            transit_times = from_quantity("transit_times", transit_times, "d")
        elif transit_times is not None and any(hasattr(v, "unit") or hasattr(v, "jd1") for v in transit_times):
            transit_times = from_quantity("transit_times", list(transit_times), "d")
        self.transit_times, self.transit_epochs = check_transit_times(
            transit_times, transit_epochs, period, t0, self.name)
        # ---- end transit times
        if not no_a and not any(isinstance(v, jax.core.Tracer) for v in (a, inc, radius, e, omega)):
            e_, w_ = np.asarray(e, float), np.deg2rad(np.asarray(omega, float))
            b = np.abs(np.asarray(a, float) * np.cos(np.deg2rad(np.asarray(inc, float)))) * (1.0 - e_**2) / (1.0 + e_ * np.sin(w_))
            # an eccentric orbit's sky distance is smallest off conjunction,
            # so a b just above 1 + radius may still graze: ask the contacts
            # a moon reaches up to a_m (1 + e_m) from its planet, and may
            # transit when the planet does not (no warning then)
            reach = max([float(np.max(np.asarray(m.a) * (1.0 + np.asarray(m.e)) + np.asarray(m.radius)))
                         for m in self.moons if not any(isinstance(v, jax.core.Tracer) for v in (m.a, m.e, m.radius))]
                        or [0.0])
            never = b >= 1.0 + np.maximum(np.asarray(radius, float), reach)
            if np.any(never) and not self.circular:
                never = never & (np.asarray(self.contacts()[1]) == 0)
            if np.any(never):
                warnings.warn(
                    f"planet {self.name!r}: inc = {np.asarray(inc, float).tolist()} deg gives |b| = {'a |cos i|' if self.circular else 'a |cos i| (1 - e^2) / (1 + e sin omega)'} = {np.max(b):.4g} >= 1 + radius, "
                    "so it never transits (inc is in degrees; a Quantity in radians is converted)",
                    UserWarning, stacklevel=user_stacklevel(),
                )

    @property
    def circular(self) -> bool:
        """Whether the circular code path serves the planet.

        True when e is a concrete 0: the equations of a circular orbit, exactly.
        A traced e (being fitted or differentiated) takes the Keplerian path,
        whose gradient in e is right also at e = 0.

        Returns
        -------
        bool
            True for a concrete e = 0.
        """
        return not isinstance(self.e, jax.core.Tracer) and not np.any(np.asarray(self.e))

    @property
    def impact(self) -> Array:
        """Impact parameter b = a cos(i) (1 - e^2) / (1 + e sin omega) [R*].

        The sky distance at conjunction, signed as the inclination gives it.
        Transits measure only |b|: ``System.positions`` places the
        planets by |b| and the hemisphere case (docs/conventions.md).

        Returns
        -------
        jax.Array
            b [R*], a scalar (or the shape of the parameters).
        """
        b = self.a * jnp.cos(jnp.deg2rad(self.inc))
        if self.circular:
            return b
        return b * (1.0 - self.e**2) / (1.0 + self.e * jnp.sin(jnp.deg2rad(self.omega)))

    def position(self, t: ArrayLike, xp=jnp) -> tuple[Array, Array, Array]:
        """Sky position (x, y, z) [R*] at times t [d].

        Circular or Keplerian orbit in the sky frame of docs/conventions.md
        (x right, y up, z towards the observer), before any tilt; with
        transit times, at ``orbit_time``. Parameters outside
        ``in_domain`` (reached under jit/grad/vmap) give NaN positions.

        Parameters
        ----------
        t : array_like
            Times [d], any shape.
        xp : module, optional
            Array namespace: ``jax.numpy`` (default) or ``numpy``, which
            evaluates eagerly on the host (geometry for concrete inputs).

        Returns
        -------
        x, y, z : array
            Coordinates [R*], each of the shape of ``t``; z > 0 in front of
            the star.
        """
        t = self.orbit_time(t, xp)
        inc = xp.deg2rad(xp.asarray(self.inc))
        a = xp.asarray(self.a)
        if not self.circular:
            pos = orbit_position(t, xp.asarray(self.period), xp.asarray(self.t0), a, inc,
                                 xp.asarray(self.e), xp.deg2rad(xp.asarray(self.omega)), xp)
        else:
            phi = 2.0 * np.pi * (xp.asarray(t) - xp.asarray(self.t0)) / xp.asarray(self.period)
            cphi = xp.cos(phi)
            pos = (a * xp.sin(phi), a * cphi * xp.cos(inc), a * cphi * xp.sin(inc))
        # the traced policy (docs/conventions.md): parameters the constructor
        # would refuse, reached under jit/grad/vmap, give NaN positions (and
        # so NaN fluxes), never a plausible number
        ok = self.in_domain(xp)
        # (their derivatives there are 0, not NaN: the NaN value is the
        # signal, which samplers and optimisers reject; NaN derivatives
        # disturbed NUTS's adaptation, R-hat 1.07 where it was 1.01)
        return tuple(xp.where(ok, v, xp.nan) for v in pos)

    def in_domain(self, xp=jnp):
        """Whether the parameters are ones the constructor accepts.

        period > 0, a > 1, radius > 0, inc in [0, 180] deg, e in [0, 1),
        periastron a (1 - e) > 1 + radius, everything finite. Concrete values
        are checked at construction; this is the same rule for traced ones.

        Parameters
        ----------
        xp : module, optional
            Array namespace: ``jax.numpy`` (default) or ``numpy``.

        Returns
        -------
        ok : array of bool
            True where the parameters are valid (the parameters' shape).
        """
        period, a, radius = xp.asarray(self.period), xp.asarray(self.a), xp.asarray(self.radius)
        inc, e, t0, omega = xp.asarray(self.inc), xp.asarray(self.e), xp.asarray(self.t0), xp.asarray(self.omega)
        finite = (xp.isfinite(period) & xp.isfinite(a) & xp.isfinite(radius) & xp.isfinite(inc) & xp.isfinite(e)
                  & xp.isfinite(t0) & xp.isfinite(omega))
        return (finite & (period > 0) & (a > 1) & (radius > 0) & (inc >= 0) & (inc <= 180) & (e >= 0) & (e < 1)
                & (a * (1.0 - e) > 1.0 + radius))

    def orbit_time(self, t: ArrayLike, xp=jnp):
        """The time [d] at which the Keplerian orbit is evaluated for time t.

        t itself on a linear ephemeris; with transit times, t minus the
        offset tc_n - t0 - n P of the listed transit nearest to t (ties: the
        later one; docs/conventions.md, "Transit times").

        Parameters
        ----------
        t : array_like
            Times [d], any shape.
        xp : module, optional
            Array namespace: ``jax.numpy`` (default) or ``numpy``.

        Returns
        -------
        array
            Orbit times [d], the shape of ``t``.
        """
        if self.transit_times is None:
            return t
        return shifted_time(t, self.transit_times, self.transit_epochs, self.period, self.t0, xp)

    def contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """First and last contact relative to conjunction t0 + n P [d].

        Circular orbits: -+ ``half_duration``. Eccentric ones are solved
        on the host (concrete parameters only) on the exact orbit, where the
        transit is not symmetric about conjunction.

        Returns
        -------
        t1, t4 : numpy.ndarray
            ``(t1 - t0, t4 - t0)`` [d], with t1 < 0 < t4; both 0 if the
            planet never transits.

        Raises
        ------
        ValueError
            When the orbit is eccentric and its parameters are traced (under
            jit/grad/vmap).
        """
        if self.circular:
            half = np.asarray(self.half_duration(), float)
            return -half, half
        if any(isinstance(getattr(self, f), jax.core.Tracer) for f in ("period", "a", "inc", "radius", "e", "omega")):
            raise ValueError(f"planet {self.name!r}: contact times of an eccentric orbit need concrete parameters, got traced ones")
        f = np.vectorize(eccentric_contacts, otypes=[float, float])
        return f(*(np.asarray(getattr(self, k), float) for k in ("period", "a", "inc", "radius", "e", "omega")))

    def half_duration(self) -> Array:
        """Half-width [d] of the window about conjunction t0 + n P that holds the whole transit.

        Half the time from first to last contact for circular orbits; for
        eccentric ones, whose transits are not symmetric about conjunction,
        the larger of the two contact offsets (see ``contacts``).

        Returns
        -------
        jax.Array
            The half-width [d]; 0 if the planet never transits.
        """
        if not self.circular:
            t1, t4 = self.contacts()
            return jnp.asarray(np.maximum(-t1, t4))
        sin_i = jnp.sin(jnp.deg2rad(self.inc))
        c2 = (1.0 - ((1.0 + self.radius) / self.a) ** 2) / jnp.maximum(sin_i**2, 1e-300)
        transits = (jnp.abs(self.impact) < 1.0 + self.radius) & (c2 < 1.0)
        phase = jnp.arccos(jnp.sqrt(jnp.clip(c2, 0.0, 1.0)))
        return jnp.where(transits, self.period * phase / (2.0 * jnp.pi), 0.0)

    def __repr__(self) -> str:
        """Planet(name='b', period=3.6961159 d, t0=134.501962 d, a=10.6 R*, inc=87.687 deg, radius=0.01805);
        eccentric orbits add e and omega [deg]."""
        fields = (("period", " d"), ("t0", " d"), ("a", " R*"), ("inc", " deg"), ("radius", ""))
        if not self.circular:
            fields += (("e", ""), ("omega", " deg"))
        fields += tuple((f, unit) for f, unit in (("lnode", " deg"), ("mass", " M_sun"))
                        if isinstance(getattr(self, f), jax.core.Tracer) or np.any(np.asarray(getattr(self, f))))
        parts = [f"name={self.name!r}"] if self.name else []
        for f, unit in fields:
            v = getattr(self, f)
            if isinstance(v, jax.core.Tracer):
                parts.append(f"{f}={v}")
                continue
            arr = np.asarray(v)
            if f == "a" and np.all(np.isnan(arr)):
                parts.append("a=None")
                continue
            parts.append(f"{f}={float(arr):.10g}{unit}" if arr.ndim == 0 else f"{f}={np.array2string(arr, precision=10)}{unit}")
        if self.transit_times is not None:
            parts.append(f"transit_times={len(self.transit_epochs)} listed (epochs {epochs_text(self.transit_epochs)})")
        if self.moons:
            parts.append(f"moons=[{', '.join(repr(m) for m in self.moons)}]")
        return "Planet(" + ", ".join(parts) + ")"

    def mid_time(self, epoch: int) -> float:
        """Predicted mid-transit time [d] of one epoch.

        The listed time of a listed epoch, else t0 + n P, plus the offset of
        the nearest listed epoch when the planet has transit times (concrete
        parameters).

        Parameters
        ----------
        epoch : int
            Transit number n (0: the transit at t0; negative before it).

        Returns
        -------
        float
            Mid-transit time [d].
        Raises
        ------
        ValueError
            When ``epoch`` is not an integer (1.5 was truncated to 1).
        """
        if isinstance(epoch, (bool, np.bool_)) or not isinstance(epoch, (int, float, np.integer, np.floating)) \
                or not np.isfinite(epoch) or int(epoch) != epoch:
            raise ValueError(f"epoch must be an integer transit number, got {epoch!r}")
        if self.transit_times is None:
            return float(self.t0) + int(epoch) * float(self.period)
        return mid_time(int(epoch), self.transit_times, self.transit_epochs, self.period, self.t0)

    def replace(self, **changes) -> "Planet":
        """A copy of the planet with some constructor arguments changed.

        The copy goes through the constructor, so its checks (and warnings)
        apply to the new values.

        Parameters
        ----------
        **changes
            New values by constructor argument name (period, t0, a, inc,
            radius, name, e, omega, transit_times, transit_epochs, lnode,
            mass, moons).

        Returns
        -------
        Planet
            The new planet.
        """
        fields = {f: getattr(self, f) for f in ("period", "t0", "a", "inc", "radius", "name", "e", "omega",
                                                  "transit_times", "transit_epochs", "lnode", "mass", "moons")}
        if not isinstance(self.a, jax.core.Tracer) and np.all(np.isnan(np.asarray(self.a))):
            fields["a"] = None
        fields.update(changes)
        return Planet(**fields)


class System(eqx.Module):
    """A star and its planets, one of which may be tilted.

    Planet ``tilted`` is the one whose orbit is rotated by alpha about the
    line of sight (Mueller et al. 2021, Sect. 2.5); the others keep their
    orbits, in the tilted planet's hemisphere or mirrored into the other
    one as the hemisphere ``case`` says (``hemisphere_cases``). An
    equinox module (a JAX pytree): the star's and planets' parameters can be
    traced; ``tilted`` is static.

    Parameters
    ----------
    star : Star
        The stellar intensity profile (and spots, if any).
    planets : sequence of Planet
        At least one planet; names, where given, must be unique.
    tilted : int or str, optional
        Index or name of the tilted planet (default 0, the first).
    orbits : str, optional
        "kepler" (default): each planet on its own Keplerian orbit (with its
        transit times, if listed). "nbody": the planets move by their mutual
        gravity, integrated by jnkepler (``pip install jaxppo[nbody]``) from
        each planet's osculating Jacobi elements at ``epoch`` (period, t0 =
        the time of inferior conjunction, e, omega, inc, lnode, mass; the
        planets' ``a`` are derived, Kepler's third law); positions at every
        time, gradients in masses and elements (docs/photodynamics.md).
    epoch : float, optional
        N-body only (required): the time [d] at which the elements osculate.
    star_mass : float or Quantity, optional
        N-body only (required): stellar mass [M_sun].
    star_radius : float or Quantity, optional
        N-body only (required): stellar radius [R_sun], the unit of the sky
        positions.
    dt : float, optional
        N-body only: the integrator's step [d]; default the shortest
        P (1 - e)^1.5 / 40 (3e-6 R* from REBOUND's IAS15 for Kepler-51).
    span : tuple of float, optional
        N-body only: (t_min, t_max) [d] the integration covers; needed when
        the times are traced (jit), where a time more than dt outside it
        gives NaN; concrete times outside it widen the grid.

    Attributes
    ----------
    star : Star
        The star.
    planets : tuple of Planet
        The planets, in the order given.
    tilted : int
        Index of the tilted planet.
    orbits : str
        "kepler" or "nbody".
    star_mass, star_radius : jax.Array or None
        N-body: stellar mass [M_sun] and radius [R_sun].
    epoch, dt, span
        N-body: as given (dt filled with its default).

    Raises
    ------
    ValueError
        When ``star`` is not a ``Star``, ``planets`` is empty or holds
        something other than a ``Planet``, two planets share a name,
        ``tilted`` is neither an index in range nor a planet's name, a
        Keplerian planet has no ``a``, or the N-body keywords are missing,
        out of range or given for Keplerian orbits (also a planet's ``a``
        that disagrees with Kepler's third law by more than 1 %).

    See Also
    --------
    Planet, Star, hemisphere_cases, alpha_limits, multi_transits

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> b = jp.Planet(period=3.6961159, t0=134.501962, a=10.60, inc=87.687, radius=0.01805, name="b")
    >>> c = jp.Planet(period=10.85408479, t0=138.60847, a=22.764, inc=89.967, radius=0.02878, name="c")
    >>> system = jp.System(jp.Star.quadratic(0.4, 0.25), [b, c], tilted="b")
    >>> system.tilted, system.index("c")
    (0, 1)
    >>> f = system.flux(np.array([134.0, 134.501962, 138.60847]))  # out of transit, b and c at mid-transit
    >>> print(np.round(np.asarray(f), 6))
    [1.       0.999621 0.998996]

    A tilt alpha [deg] rotates b's orbit about the line of sight (an array
    of tilts in ``flux`` gives one light curve per tilt, [n_alpha,
    n_times]). At b's mid-transit, alpha = 90 deg puts b on the x axis at
    x = |b|; c is behind the star (r = 0). ``xp=np`` computes on the host:

    >>> x, y, r = system.positions(134.501962, alpha=90.0, xp=np)
    >>> print(np.round(x, 4), np.round(r, 4))
    [  0.4278 -15.7555] [0.018 0.   ]
    """

    star: Star
    planets: tuple[Planet, ...]
    tilted: int = eqx.field(static=True, default=0)
    star_mass: Array | None = None
    star_radius: Array | None = None
    orbits: str = eqx.field(static=True, default="kepler")
    epoch: float | None = eqx.field(static=True, default=None)
    dt: float | None = eqx.field(static=True, default=None)
    span: tuple | None = eqx.field(static=True, default=None)

    def __init__(self, star: Star, planets, tilted: int = 0, *, orbits: str = "kepler", epoch=None,
                 star_mass=None, star_radius=None, dt=None, span=None):
        if not isinstance(star, Star):
            raise ValueError(f"star must be a jaxppo.Star, got {type(star).__name__}")
        planets = tuple(planets)
        if not planets:
            raise ValueError("planets must hold at least one Planet")
        for i, pl in enumerate(planets):
            if not isinstance(pl, Planet):
                raise ValueError(f"planets[{i}] must be a jaxppo.Planet, got {type(pl).__name__}")
        names = [pl.name for pl in planets if pl.name]
        if len(names) != len(set(names)):
            raise ValueError(f"planet names must be unique, got {names}")
        labels = [pl.name for pl in planets]
        if isinstance(tilted, str) and tilted in labels:
            tilted = labels.index(tilted)  # the tilted planet by name
        if isinstance(tilted, (bool, np.bool_)) or not isinstance(tilted, (int, np.integer)) \
                or not 0 <= int(tilted) < len(planets):
            raise ValueError(f"tilted must be a planet's index (0..{len(planets) - 1}) or name "
                             f"({[n for n in labels if n]}), got {tilted!r}")
        self.star = star
        self.tilted = int(tilted)
        if orbits == "kepler":
            given = {k: v for k, v in dict(epoch=epoch, star_mass=star_mass, star_radius=star_radius, dt=dt,
                                            span=span).items() if v is not None}
            if given:
                raise ValueError(f"{sorted(given)} apply to N-body orbits only; pass orbits='nbody' "
                                 "(Keplerian planets use each planet's a [R*])")
            for pl in planets:
                if not isinstance(pl.a, jax.core.Tracer) and np.any(np.isnan(np.asarray(pl.a))):
                    raise ValueError(f"planet {pl.name!r} has no a (semi-major axis [R*]): a Keplerian orbit needs "
                                     "it (only orbits='nbody' derives a from the masses)")
            self.planets = planets
            self.orbits, self.epoch, self.dt, self.span = "kepler", None, None, None
            self.star_mass = self.star_radius = None
        elif orbits == "nbody":
            from ._nbody import nbody_setup  # jnkepler is imported on first use only

            (self.planets, self.star_mass, self.star_radius, self.epoch, self.dt,
             self.span) = nbody_setup(planets, epoch, star_mass, star_radius, dt, span)
            self.orbits = "nbody"
        else:
            raise ValueError(f"orbits must be 'kepler' or 'nbody', got {orbits!r}")

    def index(self, name: str) -> int:
        """Index of the planet named ``name``.

        Parameters
        ----------
        name : str
            A planet's name.

        Returns
        -------
        int
            Its position in ``planets``.

        Raises
        ------
        ValueError
            When no planet has that name.
        """
        for i, pl in enumerate(self.planets):
            if pl.name == name:
                return i
        raise ValueError(f"no planet named {name!r}; names are {[p.name for p in self.planets]}")

    def positions(self, t: ArrayLike, alpha: ArrayLike = 0.0, case="same", xp=jnp):
        """Sky positions and radii (x, y, r) [R*] of the planets' disks.

        Hemispheres come from |b| only (transits cannot measure the sign of
        cos i): before the tilt every planet crosses y > 0 (y uses |cos i|);
        then ``case`` mirrors untilted planets (y -> -y) into the other
        hemisphere, and the tilted planet is rotated by alpha about the line
        of sight. So i -> 180 - i of any planet changes nothing.

        Parameters
        ----------
        t : array_like or Quantity or TimeDelta
            Times [d]; converted as in ``flux``.
        alpha : array_like or Quantity, optional
            Tilt of the tilted planet's orbit [deg] (default 0); broadcasts
            against ``t``.
        case : str or tuple of int, optional
            Hemisphere case: "same" (default, no planet mirrored),
            "opposite" (every untilted planet mirrored), a tuple of +1/-1
            signs (one per untilted planet, in planet order) or its
            "+"/"-" string (``case_label``).
        xp : module, optional
            Array namespace: ``jax.numpy`` (default) or ``numpy``, which
            computes on the host without tracing (fast geometry for concrete
            inputs).

        Returns
        -------
        x, y, r : array
            Disk centres and radii [R*], shape (broadcast of t and alpha) + [n_planets]
            (the disks on the last axis); planets behind the star get r = 0.

        Raises
        ------
        ValueError
            When ``case`` is not a valid case for this system, or ``t`` or
            ``alpha`` is a Quantity of the wrong kind.
        """
        signs = case_signs(len(self.planets), self.tilted, case)
        t = xp.asarray(from_quantity("t", t, "d"), dtype=float)
        alpha = xp.asarray(from_quantity("alpha", alpha, "deg"), dtype=float)
        if self.orbits == "nbody":
            from ._nbody import system_positions

            return system_positions(self, t, alpha, signs, xp)
        alpha_rad = xp.deg2rad(alpha)
        shape = np.broadcast_shapes(t.shape, alpha_rad.shape)
        xs, ys, rs, zs = [], [], [], []
        for i, pl in enumerate(self.planets):
            x, y, z = pl.position(t, xp)
            # |cos i| instead of cos i: the sign of b is not observable
            y = xp.where(xp.cos(xp.deg2rad(xp.asarray(pl.inc))) < 0, -y, y)
            if i != self.tilted and signs[i] < 0:
                y = -y
            node = xp.deg2rad(xp.asarray(pl.lnode))
            if i == self.tilted:
                node = node + alpha_rad
            if i == self.tilted or isinstance(pl.lnode, jax.core.Tracer) or np.any(np.asarray(pl.lnode)):
                ca, sa = xp.cos(node), xp.sin(node)
                x, y = x * ca + y * sa, -x * sa + y * ca
            xs.append(xp.broadcast_to(x, shape))
            ys.append(xp.broadcast_to(y, shape))
            rs.append(xp.broadcast_to(xp.where(z > 0, xp.asarray(pl.radius), 0.0), shape))
            zs.append(xp.broadcast_to(z, shape))
        x, y, r = xp.stack(xs, -1), xp.stack(ys, -1), xp.stack(rs, -1)
        if any(pl.moons for pl in self.planets):
            from ._moon import add_moons

            x, y, r = add_moons(self, t, alpha, signs, (x, y, xp.stack(zs, -1)), xp, kepler=True)
        return x, y, r

    def flux(self, t: ArrayLike, alpha: ArrayLike = 0.0, case="same", method: str = "auto", **kwargs) -> Array:
        """Relative flux at times t [d], planet-planet occultations included.

        The disks of ``positions`` in front of the star, integrated by
        ``occultation_flux`` (1 out of transit). A star with rotating
        spots gets the times too (its surface changes with time).

        Parameters
        ----------
        t : array_like or Quantity or TimeDelta
            Times [d], any shape. A time Quantity or an astropy
            ``TimeDelta`` is converted to days; an absolute astropy ``Time``
            is refused, because the planets' t0 are days since a zero point
            only the caller knows: pass ``t.jd - JD0`` or the TimeDelta
            ``t - Time(JD0, format="jd")`` with JD0 the zero point of t0
            (2454833.0 for BKJD).
        alpha : float or array_like or Quantity, optional
            Tilt of the tilted planet's orbit [deg] (default 0): a scalar, or
            a 1D array [n_alpha] for one light curve per tilt.
        case : str or tuple of int, optional
            Hemisphere case: "same" (default), "opposite" or a tuple of +1/-1
            signs of the untilted planets (see ``positions``,
            ``hemisphere_cases``).
        method : str, optional
            "auto" (default), "exact" or "raster"; see ``occultation_flux``.
        **kwargs
            Passed on to ``occultation_flux`` (``order``, ``chunk``,
            ``raster``, ``times``).

        Returns
        -------
        jax.Array
            Relative flux: the shape of ``t`` for a scalar ``alpha``,
            [n_alpha, *t.shape] for a 1D ``alpha``.

        Raises
        ------
        ValueError
            When a concrete ``t`` or ``alpha`` is not finite, ``alpha`` has
            more than one dimension, ``case`` is not valid for this system,
            or an input is a Quantity of the wrong kind.
        """
        t = jnp.asarray(from_quantity("t", t, "d"), float)
        if not isinstance(t, jax.core.Tracer):
            bad = ~np.isfinite(np.asarray(t))
            if bad.any():
                raise ValueError(f"t must be finite, got {float(np.asarray(t)[bad][0])} at index {np.argwhere(bad)[0].tolist()}")
        alpha = from_quantity("alpha", alpha, "deg")
        alpha = jnp.asarray(alpha, float)
        if not isinstance(alpha, jax.core.Tracer):
            bad = ~np.isfinite(np.asarray(alpha))
            if bad.any():
                raise ValueError(f"alpha must be finite [deg], got {float(np.asarray(alpha)[bad][0])}")
        if alpha.ndim > 1:
            raise ValueError(f"alpha must be a scalar or 1D array, got shape {alpha.shape}")
        if alpha.ndim == 1:
            a_grid = alpha.reshape((-1,) + (1,) * t.ndim)
            x, y, r = self.positions(t[None], a_grid, case)
        else:
            x, y, r = self.positions(t, alpha, case)
        if getattr(self.star, "spots", None) is not None and "times" not in kwargs:
            # a rotating spotted star's surface depends on time
            kwargs["times"] = jnp.broadcast_to(t, x.shape[:-1])
        return occultation_flux(self.star, x, y, r, method=method, **kwargs)

    def __repr__(self) -> str:
        tilted = self.planets[self.tilted].name or self.tilted
        inner = ",\n".join("    " + repr(p) for p in self.planets)
        extra = ""
        if self.orbits == "nbody":
            extra = (f",\n  orbits='nbody', epoch={self.epoch!r}, star_mass={self.star_mass}, "
                     f"star_radius={self.star_radius}, dt={self.dt!r}, span={self.span!r}")
        return f"System(star={self.star!r},\n  planets=[\n{inner}],\n  tilted={tilted!r}{extra})"

    def nbody_options(self) -> dict:
        """The N-body keywords of this system (empty for Keplerian orbits).

        Returns
        -------
        dict
            ``orbits``, ``epoch``, ``star_mass``, ``star_radius``, ``dt``,
            ``span`` for an N-body system, ready for ``System(...)``.
        """
        if self.orbits != "nbody":
            return {}
        return dict(orbits="nbody", epoch=self.epoch, star_mass=self.star_mass, star_radius=self.star_radius,
                    dt=self.dt, span=self.span)

    def replace(self, star: Star | None = None, planets=None, tilted: int | None = None, **nbody) -> "System":
        """A copy of the system with the star, the planets or the tilted planet changed.

        Parameters
        ----------
        star : Star, optional
            The new star (default: the same).
        planets : sequence of Planet, optional
            The new planets (default: the same).
        tilted : int or str, optional
            Index or name of the new tilted planet (default: the same index).
        **nbody
            New N-body keywords (``epoch``, ``star_mass``, ``star_radius``,
            ``dt``, ``span``; see ``System``).

        Returns
        -------
        System
            The new system (checked as by the constructor).
        """
        changed = planets is not None
        planets = self.planets if planets is None else planets
        options = {**self.nbody_options(), **nbody}
        if self.orbits == "nbody" and options.get("orbits") == "nbody":
            # a is derived again (the masses may have changed), and a default step follows new planets
            planets = [eqx.tree_at(lambda p: p.a, pl, jnp.asarray(np.nan)) for pl in planets]
            if changed and "dt" not in nbody:
                from ._nbody import default_dt

                old = [np.asarray(getattr(p, f), float) for f in ("period", "e") for p in self.planets]
                n = len(self.planets)
                if not any(isinstance(getattr(p, f), jax.core.Tracer) for p in self.planets for f in ("period", "e")) \
                        and self.dt == default_dt(old[:n], old[n:]):
                    options["dt"] = None
        return System(
            star if star is not None else self.star,
            planets,
            self.tilted if tilted is None else tilted,
            **options,
        )

    def transit_times(self, t_start, t_end):
        """The predicted mid-transit times from t_start to t_end [d].

        Same as ``jaxppo.transit_times`` of this system.

        Parameters
        ----------
        t_start, t_end : float or Quantity or TimeDelta
            The time span [d] (a time Quantity or TimeDelta is converted).

        Returns
        -------
        astropy.table.Table
            Columns ``planet``, ``epoch``, ``tc`` [d], sorted by time.
        """
        from ._transits import transit_times  # _transits builds on System

        return transit_times(self, t_start, t_end)
