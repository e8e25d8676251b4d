"""Moons: bodies on Keplerian orbits about their planet, and the sky
positions of a planet with its moons (the hierarchical approximation).

Frame: docs/conventions.md (x right, y up, z towards the observer, units
R*). A moon's relative orbit (moon minus planet) uses the equations of a
planet's orbit about the star (``jaxppo.core.geometry.orbit_position``,
the package's Kepler solver), then turns by ``lnode`` about the line of
sight like a tilt. The planet-moon barycentre follows the planet's
Keplerian orbit; the planet recoils from its moons.
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ..core.geometry import orbit_position
from ._planet import Planet
from ._units import from_quantity

__all__ = ["Moon", "hierarchical_positions", "group_offsets", "warn_if_outside_hill"]


def _check(name: str, value, lower=None, upper=None, strict_lower=True, strict_upper=False) -> None:
    """Refuse a concrete non-finite value, or one outside the bounds, naming it."""
    if isinstance(value, jax.core.Tracer):
        return
    arr = np.asarray(value, dtype=float)
    bad = ~np.isfinite(arr)
    if lower is not None:
        bad |= (arr <= lower) if strict_lower else (arr < lower)
    if upper is not None:
        bad |= (arr >= upper) if strict_upper else (arr > upper)
    if np.any(bad):
        lo = "" if lower is None else ("(" if strict_lower else "[") + f"{lower:g}, "
        hi = "" if upper is None else f"{upper:g}" + (")" if strict_upper else "]")
        where = f"in {lo}{hi}" if lower is not None and upper is not None else \
            (f"{'>' if strict_lower else '>='} {lower:g}" if lower is not None else "")
        raise ValueError(f"{name} must be finite{' and ' + where if where else ''}, got {value!r}")


class Moon(eqx.Module):
    """A moon on a Keplerian orbit about its planet.

    The orbit is that of the moon relative to the planet (moon minus
    planet), with the equations of a planet's orbit about the star
    (docs/conventions.md): with theta = f + omega - 90 deg (0 at the moon's
    inferior conjunction, where it passes in front of the planet), the
    offset is x = r sin(theta), y = r cos(theta) cos(inc),
    z = r cos(theta) sin(inc); then ``lnode`` turns it about the line of
    sight like a tilt: x' = x cos(lnode) + y sin(lnode),
    y' = -x sin(lnode) + y cos(lnode). ``inc`` = 90 deg, ``lnode`` = 0 is
    an edge-on orbit along the planet's own path across the star.
    Period and semi-major axis are independent parameters (no mass is
    derived from Kepler's third law), as in gefera (Gordon & Agol 2022).

    An equinox module (a JAX pytree): the numeric fields can be traced,
    fitted and differentiated; ``name`` is static. astropy Quantities are
    converted as for ``Planet`` (angles: any angle unit; period, t0: any
    time unit; a, radius, e, mass_ratio: dimensionless).

    Parameters
    ----------
    period : float or Quantity
        Period of the relative orbit [d], > 0.
    t0 : float or Quantity
        A time [d] of the moon's inferior conjunction (moon in front of
        the planet, theta = 0), on the planets' time scale (same zero point
        as ``Planet.t0``), also for eccentric orbits.
    a : float or Quantity
        Semi-major axis of the relative orbit [R*], > 0.
    inc : float or Quantity
        Inclination of the relative orbit to the sky [deg] in [0, 180].
    radius : float or Quantity
        Radius ratio R_moon / R* [R*], > 0.
    mass_ratio : float or Quantity, optional
        Moon mass / planet mass, >= 0 (default 0: the planet stays at the
        barycentre).
    lnode : float or Quantity, optional
        Orientation of the orbit on the sky [deg] (default 0), a rotation
        about the line of sight with the tilt's sign (above).
    e : float or Quantity, optional
        Eccentricity in [0, 1) (default 0).
    omega : float or Quantity, optional
        Argument of periastron [deg] (default 90: periastron at inferior
        conjunction), measured as for ``Planet``.
    name : str, optional
        Label (default "").

    Attributes
    ----------
    period, t0, a, inc, radius, mass_ratio, lnode, e, omega : jax.Array
        The orbit, as float arrays in the units above.
    name : str
        The label.

    Raises
    ------
    ValueError
        When a concrete parameter is not finite or out of range (period,
        a, radius <= 0; mass_ratio < 0; inc outside [0, 180] deg; e
        outside [0, 1)), or is a Quantity of the wrong kind.

    Warns
    -----
    UserWarning
        When ``mass_ratio`` > 1 (the "moon" is heavier than its planet:
        mass_ratio is m_moon / m_planet). A System also warns when a moon's
        orbit reaches outside its planet's Hill sphere
        (:func:`warn_if_outside_hill`).

    See Also
    --------
    hierarchical_positions : the planet and its moons on the sky.

    Examples
    --------
    >>> from jaxppo import Moon
    >>> m = Moon(period=1.5, t0=0.0, a=0.3, inc=90.0, radius=0.03, mass_ratio=0.01, name="b I")
    >>> x, y, z = m.offset(0.375)  # a quarter period after conjunction: beside the planet
    >>> print(f"{float(x):.4f} {float(y):.4f} {float(z):.4f}")
    0.3000 0.0000 0.0000
    """

    period: Array
    t0: Array
    a: Array
    inc: Array
    radius: Array
    mass_ratio: Array
    lnode: Array
    e: Array
    omega: Array
    name: str = eqx.field(static=True, default="")

    def __init__(self, period, t0, a, inc, radius, mass_ratio=0.0, lnode=0.0, e=0.0, omega=90.0, name: str = ""):
        units = (("period", period, "d"), ("t0", t0, "d"), ("a", a, ""), ("inc", inc, "deg"),
                 ("radius", radius, ""), ("mass_ratio", mass_ratio, ""), ("lnode", lnode, "deg"),
                 ("e", e, ""), ("omega", omega, "deg"))
        v = {k: from_quantity(k, val, unit) for k, val, unit in units}
        label = f"moon {str(name)!r}: " if name else "moon: "
        for k in ("period", "a", "radius"):
            _check(label + k, v[k], lower=0.0)
        _check(label + "mass_ratio", v["mass_ratio"], lower=0.0, strict_lower=False)
        _check(label + "inc [deg]", v["inc"], lower=0.0, upper=180.0, strict_lower=False)
        _check(label + "e (eccentricity)", v["e"], lower=0.0, upper=1.0, strict_lower=False, strict_upper=True)
        for k in ("t0", "lnode", "omega"):
            _check(label + k, v[k])
        for k, val in v.items():
            setattr(self, k, jnp.asarray(val, float))
        self.name = str(name)
        q = v["mass_ratio"]
        if not isinstance(q, jax.core.Tracer) and np.any(np.asarray(q, float) > 1.0):
            from ._planet import user_stacklevel

            warnings.warn(f"{label}mass_ratio = {np.asarray(q, float).tolist()} makes the moon heavier than its "
                          "planet (mass_ratio is m_moon / m_planet; the planet's orbit is that of their barycentre)",
                          UserWarning, stacklevel=user_stacklevel())

    def in_domain(self, xp=jnp):
        """Whether the parameters are ones the constructor accepts.

        The constructor's rule for traced values (under jit/grad/vmap),
        where ``offset`` then gives NaN, as ``Planet.position`` does.

        Parameters
        ----------
        xp : module, optional
            Array namespace: ``jax.numpy`` (default) or ``numpy``.

        Returns
        -------
        ok : array of bool
            True where the parameters are valid (the parameters' shape).

        Examples
        --------
        >>> from jaxppo import Moon
        >>> bool(Moon(1.5, 0.0, 0.3, 90.0, 0.03).in_domain())
        True
        """
        f = {k: xp.asarray(getattr(self, k)) for k in
             ("period", "t0", "a", "inc", "radius", "mass_ratio", "lnode", "e", "omega")}
        finite = True
        for val in f.values():
            finite = finite & xp.isfinite(val)
        return (finite & (f["period"] > 0) & (f["a"] > 0) & (f["radius"] > 0) & (f["mass_ratio"] >= 0)
                & (f["inc"] >= 0) & (f["inc"] <= 180) & (f["e"] >= 0) & (f["e"] < 1))

    def offset(self, t: ArrayLike, xp=jnp) -> tuple[Array, Array, Array]:
        """Sky offset (x, y, z) [R*] of the moon from its planet at times t [d].

        The relative orbit of the class docstring (the Kepler solver of
        ``Planet.position``, ``jaxppo.core.geometry.orbit_position``),
        turned by ``lnode``. Out-of-domain parameters give NaN.
        Differentiable in every element, with finite gradients also at
        e = 0.

        Parameters
        ----------
        t : array_like or Quantity
            Times [d], any shape.
        xp : module, optional
            Array namespace: ``jax.numpy`` (default) or ``numpy``.

        Returns
        -------
        x, y, z : array
            Moon minus planet [R*], each of the shape of ``t`` (broadcast
            with the parameters); z > 0: the moon is nearer the observer.

        Examples
        --------
        >>> from jaxppo import Moon
        >>> m = Moon(period=2.0, t0=0.0, a=0.25, inc=60.0, radius=0.02, lnode=90.0)
        >>> x, y, z = m.offset(0.0)  # conjunction: y = a cos(inc) before the turn by lnode
        >>> print(f"{float(x):.4f} {float(y):.4f} {float(z):.4f}")
        0.1250 0.0000 0.2165
        """
        t = xp.asarray(from_quantity("t", t, "d"), dtype=float)
        x, y, z = orbit_position(t, xp.asarray(self.period), xp.asarray(self.t0), xp.asarray(self.a),
                                 xp.deg2rad(xp.asarray(self.inc)), xp.asarray(self.e),
                                 xp.deg2rad(xp.asarray(self.omega)), xp)
        node = xp.deg2rad(xp.asarray(self.lnode))
        cn, sn = xp.cos(node), xp.sin(node)
        x, y = x * cn + y * sn, -x * sn + y * cn
        ok = self.in_domain(xp)
        return tuple(xp.where(ok, v, xp.nan) for v in (x, y, z))

    def __repr__(self) -> str:
        """Moon(name='b I', period=1.5 d, ...) with the units of the fields."""
        fields = (("period", " d"), ("t0", " d"), ("a", " R*"), ("inc", " deg"), ("radius", ""),
                  ("mass_ratio", ""), ("lnode", " deg"), ("e", ""), ("omega", " deg"))
        parts = [f"name={self.name!r}"] if self.name else []
        for f, unit in fields:
            v = getattr(self, f)
            if isinstance(v, jax.core.Tracer) or np.ndim(v):
                parts.append(f"{f}={v}")
            else:
                parts.append(f"{f}={float(v):.10g}{unit}")
        return "Moon(" + ", ".join(parts) + ")"


def _check_group(planet, moons) -> tuple:
    if not isinstance(planet, Planet):
        raise ValueError(f"planet must be a jaxppo.Planet, got {type(planet).__name__}")
    if isinstance(moons, Moon):
        moons = (moons,)
    moons = tuple(moons)
    for k, m in enumerate(moons):
        if not isinstance(m, Moon):
            raise ValueError(f"moons[{k}] must be a Moon, got {type(m).__name__}")
    traced = any(isinstance(getattr(b, f), jax.core.Tracer) for b in moons for f in ("a", "e", "radius"))
    if not traced and not isinstance(planet.radius, jax.core.Tracer):
        for k, m in enumerate(moons):
            peri = np.asarray(m.a, float) * (1.0 - np.asarray(m.e, float))
            touch = float(np.max(np.asarray(planet.radius, float) + np.asarray(m.radius, float)))
            if np.any(peri <= touch):
                raise ValueError(
                    f"moons[{k}]{f' ({m.name!r})' if m.name else ''}: periapsis a (1 - e) = {float(np.min(peri)):.4g} R* <= planet radius "
                    f"+ moon radius = {touch:.4g} R*, so the moon would hit its planet")
    return moons


def hierarchical_positions(planet: Planet, moons, t: ArrayLike, xp=jnp) -> tuple[Array, Array, Array]:
    """Sky positions (x, y, z) [R*] of a planet and its moons at times t [d].

    The barycentre of the planet and its moons follows ``planet.position``
    (its Keplerian orbit about the star). The hierarchical approximation,
    for any number of moons: each moon k is on its own Keplerian orbit
    about the planet, offset s_k = ``moons[k].offset(t)`` (the moons do not
    perturb each other), and the barycentre is the mass-weighted mean, so
    with mass ratios q_k = m_k / M_planet the planet is displaced from the
    barycentre B by -sum_k q_k s_k / (1 + sum_j q_j), and moon k is at
    planet + s_k. With
    one moon this is gefera's ``HierarchicalSystem`` (planet at
    B - q s / (1 + q), moon at B + s / (1 + q)).

    Positions only: ``System`` places the disks, gives r = 0 to those with
    z <= 0 (behind the star) and applies its mirror (|cos i|, hemisphere
    case) and tilt to the planet's position; apply them to all the bodies
    of the group alike, so that the moons keep their places about the
    planet. jit-, grad- and vmap-able; out-of-domain parameters (traced),
    a moon hitting its planet included, give NaN for the whole group.

    Parameters
    ----------
    planet : Planet
        The planet; its orbit is that of the planet-moon barycentre and
        ``planet.radius`` enters the collision check only.
    moons : Moon or sequence of Moon
        The planet's moons (an empty sequence gives the planet alone).
    t : array_like or Quantity
        Times [d], any shape.
    xp : module, optional
        Array namespace: ``jax.numpy`` (default) or ``numpy``.

    Returns
    -------
    x, y, z : array
        Coordinates [R*], shape [*t.shape, 1 + n_moons]: the planet first,
        then the moons in the order given.

    Raises
    ------
    ValueError
        When ``planet`` is not a ``Planet``, a moon is not a ``Moon``, or
        (concrete parameters) a moon's periapsis a (1 - e) does not exceed
        the planet's radius plus its own (the moon would hit the planet).

    Examples
    --------
    A planet at mid-transit with one moon a quarter period past
    conjunction, beside the planet along x; the planet recoils by
    -q a / (1 + q):

    >>> from jaxppo import Planet
    >>> from jaxppo import Moon
    >>> from jaxppo.model._moon import hierarchical_positions
    >>> pl = Planet(period=30.0, t0=0.0, a=50.0, inc=90.0, radius=0.1)
    >>> moon = Moon(period=1.6, t0=-0.4, a=0.4, inc=90.0, radius=0.03, mass_ratio=0.25)
    >>> x, y, z = hierarchical_positions(pl, [moon], 0.0)
    >>> print(x.shape, [round(float(v), 4) for v in x])
    (2,) [-0.08, 0.32]
    """
    t = xp.asarray(from_quantity("t", t, "d"), dtype=float)
    bary = planet.position(t, xp)
    return tuple(b[..., None] + d for b, d in zip(bary, group_offsets(planet, moons, t, xp)))


def group_offsets(planet: Planet, moons, t: ArrayLike, xp=jnp) -> tuple[Array, Array, Array]:
    """Offsets (x, y, z) [R*] of a planet and its moons from their barycentre.

    The hierarchical approximation of :func:`hierarchical_positions`
    (which adds them to the barycentre's orbit): each moon k at s_k from
    the planet, the planet at -sum q_k s_k / (1 + sum q_j).

    Parameters
    ----------
    planet : Planet
        The planet (its radius: the collision check).
    moons : sequence of Moon
        Its moons.
    t : array_like
        Times [d], any shape.
    xp : module, optional
        Array namespace: ``jax.numpy`` (default) or ``numpy``.

    Returns
    -------
    x, y, z : array
        Offsets [R*], shape [*t.shape, 1 + n_moons], the planet first.

    Raises
    ------
    ValueError
        As :func:`hierarchical_positions`.
    """
    moons = _check_group(planet, moons)
    t = xp.asarray(t, dtype=float)
    offsets = []
    for m in moons:
        # the traced form of _check_group's rule: a moon that would hit its
        # planet makes the whole group NaN
        clear = xp.asarray(m.a) * (1.0 - xp.asarray(m.e)) > xp.asarray(planet.radius) + xp.asarray(m.radius)
        offsets.append(tuple(xp.where(clear, v, xp.nan) for v in m.offset(t, xp)))
    q = [xp.asarray(m.mass_ratio) for m in moons]
    total = 1.0 + sum(q)
    out = []
    for c in range(3):
        shift = sum(qk * s[c] for qk, s in zip(q, offsets)) / total if moons else xp.zeros(t.shape)
        cols = xp.broadcast_arrays(-shift, *(s[c] - shift for s in offsets))
        out.append(xp.stack(cols, -1))
    return tuple(out)


def check_moons(planet_radius, moons) -> tuple:
    """The moons of a planet of radius ``planet_radius`` as a tuple, checked
    (``Planet(moons=...)``: each a Moon, none hitting the planet)."""
    probe = Planet(period=1.0, t0=0.0, a=None, inc=90.0, radius=planet_radius) \
        if not isinstance(planet_radius, jax.core.Tracer) else None
    moons = (tuple(moons) if not isinstance(moons, Moon) else (moons,)) if probe is None else \
        _check_group(probe, moons)
    # their labels in free-parameter names ("b.I.a"; "moon<k>" when unnamed) must be unique and free of "."
    labels = [m.name or f"moon{k}" for k, m in enumerate(moons)]
    if len(set(labels)) != len(labels) or any("." in n for n in labels):
        raise ValueError(f"moon names must be unique and without '.' (unnamed moons are 'moon<k>'), got {labels}")
    return moons


def add_moons(system, t, alpha, signs, bary, xp, kepler: bool):
    """The disks (x, y, r) of a System whose planets have moons.

    ``bary``: the sky positions (x, y, z) [R*] of the planets' orbits (the
    barycentres), [*shape, n_planets], after the System's transforms. Each
    group's offsets (:func:`group_offsets`) take the same transforms (the
    Keplerian |cos i| mirror, the hemisphere case's mirror, the turn by the
    planet's node and, for the tilted planet, alpha); the planets' disks
    move by their recoil, and the moons' disks follow the planets', in
    planet order."""
    x, y, z = bary
    shape = x.shape[:-1]
    alpha_rad = xp.deg2rad(xp.asarray(alpha, dtype=float))
    px, py, pz, mx, my, mz, mr = [], [], [], [], [], [], []
    for i, pl in enumerate(system.planets):
        xi, yi, zi = x[..., i], y[..., i], z[..., i]
        if not pl.moons:
            px.append(xi), py.append(yi), pz.append(zi)
            continue
        dx, dy, dz = group_offsets(pl, pl.moons, t, xp)
        flip = i != system.tilted and signs[i] < 0
        if kepler:
            flip = xp.logical_xor(flip, xp.cos(xp.deg2rad(xp.asarray(pl.inc))) < 0)
        dy = xp.where(flip, -dy, dy)
        node = xp.deg2rad(xp.asarray(pl.lnode)) + (alpha_rad if i == system.tilted else 0.0)
        node = xp.asarray(node)[..., None]
        cn, sn = xp.cos(node), xp.sin(node)
        dx, dy = dx * cn + dy * sn, -dx * sn + dy * cn
        gx, gy, gz = (xp.broadcast_to(b[..., None] + d, shape + (d.shape[-1],)) for b, d in
                      ((xi, dx), (yi, dy), (zi, dz)))
        px.append(gx[..., 0]), py.append(gy[..., 0]), pz.append(gz[..., 0])
        mx.append(gx[..., 1:]), my.append(gy[..., 1:]), mz.append(gz[..., 1:])
        mr.append(xp.stack([xp.asarray(m.radius) for m in pl.moons]))
    radius = xp.stack([xp.asarray(pl.radius) for pl in system.planets])
    pz = xp.stack(pz, -1)
    x = xp.concatenate([xp.stack(px, -1)] + mx, -1)
    y = xp.concatenate([xp.stack(py, -1)] + my, -1)
    z = xp.concatenate([pz] + mz, -1)
    r = xp.where(z > 0, xp.concatenate([radius] + mr), 0.0)
    return x, y, r


def warn_if_outside_hill(system) -> None:
    """Warn (UserWarning) for each moon whose orbit reaches outside its
    planet's Hill sphere, where the star, not the planet, holds it.

    The moon's apoapsis a_m (1 + e_m) is compared with the Hill radius at
    the planet's periastron, r_H = a (1 - e) (mu / 3)^(1/3) [R*], mu the
    mass ratio of the planet (with its moons) to the star, capped at 1.
    N-body planets: mu = mass / star_mass. Keplerian planets carry no
    mass, so mu is the one the moon's own orbit implies by Kepler's third
    law, mu = (a_m / a)^3 (P / P_m)^2 (a moon's period and a are
    independent parameters); for circular orbits the test is then
    P_m > P / sqrt(3), free of any mass. Traced values are not checked.

    Parameters
    ----------
    system : jaxppo.System
        The system whose planets' moons are checked.

    Examples
    --------
    >>> import warnings
    >>> import jaxppo as jp
    >>> moon = jp.Moon(period=1.2, t0=0.0, a=500.0, inc=90.0, radius=0.01, name="I")
    >>> planet = jp.Planet(period=40.0, t0=0.0, a=60.0, inc=90.0, radius=0.1, moons=[moon], name="b")
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     system = jp.System(jp.Star.uniform(), [planet])  # System() calls warn_if_outside_hill
    >>> print("outside the planet's Hill sphere" in str(caught[0].message))
    True
    """
    for pl in system.planets:
        if not pl.moons:
            continue
        values = [pl.a, pl.e, pl.period, pl.mass] + [v for m in pl.moons for v in (m.a, m.e, m.period)]
        if system.orbits == "nbody":
            values.append(system.star_mass)
        if any(isinstance(v, jax.core.Tracer) for v in values) or any(np.ndim(v) for v in values):
            continue
        a, e, period = float(pl.a), float(pl.e), float(pl.period)
        for k, m in enumerate(pl.moons):
            apo = float(m.a) * (1.0 + float(m.e))
            if system.orbits == "nbody":
                mu = float(pl.mass) / float(system.star_mass)
                why = f"planet-to-star mass ratio {mu:.3g} (its mass, with its moons)"
            else:
                mu = (float(m.a) / a) ** 3 * (period / float(m.period)) ** 2
                why = (f"planet-to-star mass ratio {mu:.3g}{' (more than the star: taken as 1)' if mu > 1 else ''}, "
                       "the one the moon's a and period imply by Kepler's third law (a Keplerian planet has no mass)")
            r_hill = a * (1.0 - e) * (min(mu, 1.0) / 3.0) ** (1.0 / 3.0)
            if apo > r_hill:
                from ._planet import user_stacklevel

                warnings.warn(
                    f"moon {m.name or f'moon{k}'!r} of planet {pl.name!r}: its orbit reaches {apo:.4g} R* from the "
                    f"planet, outside the planet's Hill sphere ({r_hill:.4g} R* at the planet's periastron, for a "
                    f"{why}), where the star and not the planet holds it: the Keplerian moon orbit is not "
                    "physical (a is in stellar radii, period in days)", UserWarning, stacklevel=user_stacklevel())
