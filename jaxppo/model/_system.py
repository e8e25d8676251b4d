"""A star and its planets, the tilt alpha of one orbit and the sky
positions and flux of every planet (hemisphere cases: ``._cases``;
multi-transits: ``._transits``).

Frame and equations: docs/conventions.md (sky frame x right, y up, z to the
observer; Mueller et al. 2021, Sect. 2.5 and Eqs. 2-6).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._cases import case_signs
from ._flux import occultation_flux
from ._planet import Planet
from ._programs import stored
from ._star import Star
from ._units import from_quantity

__all__ = ["require_keplerian", "System"]


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
            for field in ("period", "t0", "a", "inc", "radius", "e", "omega", "lnode", "mass"):
                value = getattr(pl, field)  # one orbit per planet: an array broadcast against the times
                if not isinstance(value, jax.core.Tracer) and np.ndim(value) != 0:
                    raise ValueError(f"planet {pl.name or i!r}: {field} must be one number in a System, got shape "
                                     f"{np.shape(value)}: {np.asarray(value)!r} (one Planet per orbit)")
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
        if any(pl.moons for pl in self.planets):
            from ._moon import warn_if_outside_hill

            warn_if_outside_hill(self)  # a UserWarning, not an error: the model is still defined

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
        x, y, r, z = _kepler_positions(self.planets, self.tilted, signs, t, alpha, xp)
        if any(pl.moons for pl in self.planets):
            from ._moon import add_moons

            x, y, r = add_moons(self, t, alpha, signs, (x, y, z), xp, kepler=True)
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
            t, alpha = t[None], alpha.reshape((-1,) + (1,) * t.ndim)
        x, y, r = _sky_positions(self, t, alpha, case)
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
            if (changed or "star_mass" in nbody) and "dt" not in nbody:
                from ._nbody import default_dt

                fields = ("period", "e", "mass")
                if not any(isinstance(getattr(p, f), jax.core.Tracer) for p in self.planets for f in fields) \
                        and not isinstance(self.star_mass, jax.core.Tracer):
                    old = [[float(getattr(p, f)) for p in self.planets] for f in fields]
                    if self.dt == default_dt(old[0], old[1], np.asarray(old[2]) / float(self.star_mass)):
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


def _kepler_positions(planets, tilted: int, signs, t, alpha, xp):
    """(x, y, r, z) [R*] of Keplerian ``planets`` (last axis) at times t and
    tilt alpha [deg] (broadcast): ``System.positions`` without moons, with
    the hemisphere signs of ``case_signs``."""
    alpha_rad = xp.deg2rad(alpha)
    shape = np.broadcast_shapes(t.shape, alpha_rad.shape)
    xs, ys, rs, zs = [], [], [], []
    for i, pl in enumerate(planets):
        x, y, z = pl.position(t, xp)
        # |cos i| instead of cos i: the sign of b is not observable
        y = xp.where(xp.cos(xp.deg2rad(xp.asarray(pl.inc))) < 0, -y, y)
        if i != tilted and signs[i] < 0:
            y = -y
        node = xp.deg2rad(xp.asarray(pl.lnode))
        if i == tilted:
            node = node + alpha_rad
        if i == tilted or isinstance(pl.lnode, jax.core.Tracer) or np.any(np.asarray(pl.lnode)):
            ca, sa = xp.cos(node), xp.sin(node)
            x, y = x * ca + y * sa, -x * sa + y * ca
        xs.append(xp.broadcast_to(x, shape))
        ys.append(xp.broadcast_to(y, shape))
        rs.append(xp.broadcast_to(xp.where(z > 0, xp.asarray(pl.radius), 0.0), shape))
        zs.append(xp.broadcast_to(z, shape))
    x, y, r = xp.stack(xs, -1), xp.stack(ys, -1), xp.stack(rs, -1)
    return x, y, r, xp.stack(zs, -1)


def _sky_positions(system: System, t, alpha, case):
    """``system.positions(t, alpha, case)``; with concrete inputs, Keplerian
    orbits and no moons, as one stored program (``_positions_program``)
    instead of some thirty operations compiled one by one (0.7 s of a new
    process's first ``flux``, on a 2-core CPU)."""
    if (system.orbits == "nbody" or any(pl.moons for pl in system.planets)
            or any(isinstance(v, jax.core.Tracer) for v in jax.tree_util.tree_leaves((system, t, alpha)))):
        return system.positions(t, alpha, case)
    signs = tuple(int(v) for v in case_signs(len(system.planets), system.tilted, case))  # its errors, as positions'
    # the program's inputs are the planets' orbital values (not the star, not
    # the names: one program for every system of the same planets and
    # shapes); a concrete e = 0 or lnode = 0 is left out and so stays the
    # constructor's concrete 0 inside it: a circular orbit keeps its own
    # equations and an unrotated node its skipped rotation, as here
    orbits = []
    for pl in system.planets:
        values = {k: getattr(pl, k) for k in ("period", "t0", "a", "inc", "radius", "transit_times", "transit_epochs")}
        if not pl.circular:
            values.update(e=pl.e, omega=pl.omega)
        if np.any(np.asarray(pl.lnode)):
            values["lnode"] = pl.lnode
        orbits.append(values)
    x, y, r, _ = _positions_program(tuple(orbits), system.tilted, signs, jnp.asarray(t), jnp.asarray(alpha))
    return x, y, r


@stored(filtered=True, static_argnames=("tilted", "signs"))
def _positions_program(orbits, tilted, signs, t, alpha):
    """``_kepler_positions`` of the planets made from ``orbits`` (each a
    dict of Planet's arguments)."""
    return _kepler_positions([Planet(**values) for values in orbits], tilted, signs, t, alpha, jnp)
