"""A planet on a circular or eccentric orbit (with listed transit times,
moons, or N-body elements), in the sky frame of docs/conventions.md (x
right, y up, z to the observer; Mueller et al. 2021, Sect. 2.5 and
Eqs. 2-6; eccentric orbits as in Winn 2010).
"""

from __future__ import annotations

import os
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ..core.geometry import orbit_position
from ._contacts import eccentric_contacts
from ._ttv import check_transit_times, epochs_text, mid_time, shifted_time
from ._units import from_quantity

__all__ = ["Planet", "check_periastron", "never_transits", "warn_if_never_transits"]


def _positive(name: str, value, *, strict=True, lower=0.0) -> None:
    if isinstance(value, jax.core.Tracer):
        return
    if value is None:
        raise ValueError(f"{name} must be a number, got None")
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    bad = arr <= lower if strict else arr < lower
    if np.any(bad):
        op = ">" if strict else ">="
        raise ValueError(f"{name} must be {op} {lower}, got {value!r}")


def check_periastron(name: str, a, e, radius, why: str = "") -> None:
    """Refuse an orbit whose periastron a (1 - e) [R*] is not clear of the
    star (<= 1 + radius), naming the planet; traced values pass. ``why``:
    where ``a`` comes from, when the user did not give it."""
    if any(isinstance(v, jax.core.Tracer) for v in (a, e, radius)):
        return
    peri = np.asarray(a, float) * (1.0 - np.asarray(e, float))
    if np.any(peri <= 1.0 + np.asarray(radius, float)):
        raise ValueError(
            f"planet {name!r}: a = {np.min(np.asarray(a, float)):.4g} R*{why} and e = {np.max(np.asarray(e, float)):.4g} put periastron at "
            f"a (1 - e) = {np.min(peri):.4g} R* <= 1 + radius = {1.0 + np.max(np.asarray(radius, float)):.4g} R*, so "
            "the planet would hit the star")


def never_transits(planet):
    """|b| [R*] of a planet whose orbit never crosses the stellar disk
    (|b| >= 1 + radius, and for an eccentric orbit no contacts; a moon
    reaches up to a_m (1 + e_m) from its planet and may transit when the
    planet does not), else None; None too for traced values or a = None."""
    fields = (planet.a, planet.inc, planet.radius, planet.e, planet.omega)
    if any(isinstance(v, jax.core.Tracer) for v in fields) or np.any(np.isnan(np.asarray(planet.a, float))):
        return None
    a, inc, radius, e_ = (np.asarray(v, float) for v in fields[:4])
    w_ = np.deg2rad(np.asarray(planet.omega, float))
    b = np.abs(a * np.cos(np.deg2rad(inc))) * (1.0 - e_**2) / (1.0 + e_ * np.sin(w_))
    # an eccentric orbit's sky distance is smallest off conjunction, so a b
    # just above 1 + radius may still graze: ask the contacts
    reach = max([float(np.max(np.asarray(m.a) * (1.0 + np.asarray(m.e)) + np.asarray(m.radius)))
                 for m in planet.moons if not any(isinstance(v, jax.core.Tracer) for v in (m.a, m.e, m.radius))]
                or [0.0])
    never = b >= 1.0 + np.maximum(radius, reach)
    if np.any(never) and not planet.circular:
        never = never & (np.asarray(planet.contacts()[1]) == 0)
    return float(np.max(b)) if np.any(never) else None


def warn_if_never_transits(planet, orbit: str = "") -> None:
    """Warn when a planet's orbit never crosses the stellar disk
    (``never_transits``): usually an inclination in radians, or a unit
    slip in a or the star's size. ``orbit``: what orbit is meant, for the
    message (N-body planets: their osculating orbit at the epoch)."""
    b = never_transits(planet)
    if b is not None:
        inc, a = np.asarray(planet.inc, float), np.asarray(planet.a, float)
        formula = "a |cos i|" if planet.circular else "a |cos i| (1 - e^2) / (1 + e sin omega)"
        warnings.warn(
            f"planet {planet.name!r}{orbit}: inc = {inc.tolist()} deg and a = {np.max(a):.4g} R* give |b| = {formula} "
            f"= {b:.4g} >= 1 + radius, so it never transits (inc is in degrees, a in stellar radii; a "
            "Quantity is converted)",
            UserWarning, stacklevel=user_stacklevel(),
        )


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
        who = f"planet {str(name)!r}: " if str(name) else ""  # errors name the planet
        _positive(who + "period", period)
        _positive(who + "t0", t0, strict=False, lower=-np.inf)
        if not no_a:
            _positive(who + "a", a, lower=1.0)
        _positive(who + "radius", radius)
        _positive(who + "omega", omega, strict=False, lower=-np.inf)
        lnode = from_quantity("lnode", lnode, "deg")
        mass = from_quantity("mass", mass, "M_sun")
        _positive(who + "lnode", lnode, strict=False, lower=-np.inf)
        _positive(who + "mass", mass, strict=False)
        if not isinstance(inc, jax.core.Tracer):
            inc_arr = np.asarray(inc, dtype=float)
            if not np.all(np.isfinite(inc_arr)) or np.any((inc_arr < 0) | (inc_arr > 180)):
                raise ValueError(f"{who}inc must be in [0, 180] degrees, got {inc!r}")
        if not isinstance(e, jax.core.Tracer):
            e_arr = np.asarray(e, dtype=float)
            if not np.all(np.isfinite(e_arr)) or np.any((e_arr < 0) | (e_arr >= 1)):
                raise ValueError(f"{who}e (eccentricity) must be in [0, 1), got {e!r}")
            if not no_a:
                check_periastron(str(name), a, e, radius)
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
        if not no_a:
            warn_if_never_transits(self)

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
        numpy.ndarray or jax.Array
            b [R*], a scalar (or the shape of the parameters): a numpy array
            for concrete parameters, traced under jit/grad/vmap.
        """
        xp = self._xp()
        b = xp.asarray(self.a) * xp.cos(xp.deg2rad(xp.asarray(self.inc)))
        if self.circular:
            return b
        e = xp.asarray(self.e)
        return b * (1.0 - e**2) / (1.0 + e * xp.sin(xp.deg2rad(xp.asarray(self.omega))))

    def _xp(self):
        """numpy where every parameter is concrete (host arithmetic: no
        device program per operation), else jax.numpy."""
        return jnp if any(isinstance(v, jax.core.Tracer) for v in jax.tree_util.tree_leaves(self)) else np

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
        numpy.ndarray or jax.Array
            The half-width [d]; 0 if the planet never transits (a numpy
            array for concrete parameters, traced under jit/grad/vmap).
        """
        if not self.circular:
            t1, t4 = self.contacts()
            return np.maximum(-t1, t4)
        xp = self._xp()
        radius, a = xp.asarray(self.radius), xp.asarray(self.a)
        sin_i = xp.sin(xp.deg2rad(xp.asarray(self.inc)))
        c2 = (1.0 - ((1.0 + radius) / a) ** 2) / xp.maximum(sin_i**2, 1e-300)
        transits = (xp.abs(self.impact) < 1.0 + radius) & (c2 < 1.0)
        phase = xp.arccos(xp.sqrt(xp.clip(c2, 0.0, 1.0)))
        return xp.where(transits, xp.asarray(self.period) * phase / (2.0 * np.pi), 0.0)

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
