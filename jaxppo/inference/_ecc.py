"""Eccentricity and argument of periastron as free parameters:
``"b.secosw"``, ``"b.sesinw"`` = sqrt(e) cos(omega), sqrt(e) sin(omega)
(Eastman et al. 2013; omega in the planet's convention, degrees, 90 =
periastron at transit), freed together.

The fit coordinates (x, y) of the pair map onto the open disk
sqrt(e) < sqrt(e_cap) by the radial map sqrt(e) = c tanh(r / c),
r = |(x, y)|, c = sqrt(e_cap) (identity near e = 0, smooth, bounded), so
every coordinate is an orbit with e < e_cap. e_cap = 1 - (1 + p) / a is
taken from the starting system (a: its a [R*], for N-body planets the
osculating a Kepler's third law gives from the starting masses and period;
p: its radius): the orbit with e = e_cap grazes the star at periastron.
Where a or the radius move during a fit (or an N-body planet's mass or
period), periastron may still enter the star; the model flux is NaN there
(``periastron_ok``), which a fit's step rejects and NUTS counts as a
divergence. For N-body planets e and omega are the osculating elements at
the system's epoch. The singular points of
sqrt and arctan2 at e = 0 are taken with the double-``where`` form, so
gradients are finite (and right) at secosw = sesinw = 0.
"""

from __future__ import annotations

import jax.numpy as jnp

__all__ = ["ECC_PARAMS", "ECC_START", "off_circular", "ecc_cap", "pair_from_theta", "theta_from_pair", "e_omega", "pair_of", "periastron_ok", "conjunction_factor"]

ECC_PARAMS = ("secosw", "sesinw")
"""The eccentricity pair of each planet a fit or a sampler may free."""


ECC_START = 0.01
"""The eccentricity a fit or a sampler starts from when the pair is free
and the planet's start is circular: at e = 0 chi^2 is stationary in
(secosw, sesinw) (e cos omega and e sin omega are second order in them),
so a start there never moves (the fit stopped with "the data do not
constrain" the pair)."""


def off_circular(system, slots):
    """``system`` with every planet whose pair is free (``slots``: the
    model's (planet, parameter) slots) and whose concrete e is 0 moved to
    e = ``ECC_START``, omega = 90 deg (periastron at transit: the same
    transit to first order)."""
    owners = sorted({o for o, p in slots if p in ECC_PARAMS and o != "star" and o != "lc"})
    planets = list(system.planets)
    moved = False
    for k in owners:
        try:
            circular = float(planets[k].e) == 0.0
        except TypeError:  # traced: left as it is
            circular = False
        if circular:
            planets[k] = planets[k].replace(e=ECC_START, omega=90.0)
            moved = True
    return system.replace(planets=planets) if moved else system


def ecc_cap(base, k: int):
    """e_cap = 1 - (1 + p) / a of planet ``k`` of the system ``base`` (the
    start; an N-body system's planets carry the a it derives from their
    periods and the starting masses; traceable)."""
    pl = base.planets[k]
    return 1.0 - (1.0 + pl.radius) / pl.a


def _ratio(r2, c, inverse: bool):
    """g(r^2) = c tanh(r / c) / r (``inverse``: c artanh(r / c) / r, r
    clipped into the disk), 1 at r = 0 with the double-where form."""
    pos = r2 > 0.0
    r = jnp.sqrt(jnp.where(pos, r2, 1.0))
    if inverse:
        v = c * jnp.arctanh(jnp.minimum(r / c, 1.0 - 1e-12)) / r
    else:
        v = c * jnp.tanh(r / c) / r
    return jnp.where(pos, v, 1.0)


def pair_from_theta(x, y, cap):
    """(secosw, sesinw) of the fit coordinates (x, y) of a planet with
    e_cap ``cap`` (module docstring)."""
    g = _ratio(x**2 + y**2, jnp.sqrt(cap), False)
    return x * g, y * g


def theta_from_pair(sx, sy, cap):
    """The fit coordinates (x, y) of (secosw, sesinw) = (sx, sy): the
    inverse of ``pair_from_theta`` (a point on or outside the disk
    sqrt(e) < sqrt(cap) is pulled just inside)."""
    g = _ratio(sx**2 + sy**2, jnp.sqrt(cap), True)
    return sx * g, sy * g


def e_omega(sx, sy):
    """(e, omega [deg]) of (secosw, sesinw); omega = 90 deg at e = 0 (any
    omega is that orbit), with a zero, finite derivative there."""
    e = sx**2 + sy**2
    pos = e > 0.0
    w = jnp.rad2deg(jnp.arctan2(jnp.where(pos, sy, 1.0), jnp.where(pos, sx, 0.0)))
    return e, jnp.where(pos, w, 90.0)


def pair_of(e, omega):
    """(secosw, sesinw) of a planet's e and omega [deg] (sqrt(0) taken
    safely)."""
    pos = e > 0.0
    s = jnp.where(pos, jnp.sqrt(jnp.where(pos, e, 1.0)), 0.0)
    w = jnp.deg2rad(omega)
    return s * jnp.cos(w), s * jnp.sin(w)


def periastron_ok(planet):
    """Whether a (1 - e) > 1 + radius: the orbit clears the star."""
    return planet.a * (1.0 - planet.e) > 1.0 + planet.radius


def conjunction_factor(e, omega):
    """(1 - e^2) / (1 + e sin omega): the star-planet distance at
    conjunction in units of a, so that the impact parameter
    (``Planet.impact``) is b = a cos i times it (1 for a circular orbit,
    exactly); the inverse maps of ``._model`` take it from here. The fit and
    sampling coordinate of a free inclination is this b / (1 + p): with
    a cos i / (1 + p) instead, an eccentric planet that transits with
    a cos i > 1 + p lay outside the coordinate's range (a fit started at
    it was silently moved, and ``sample`` refused it as not transiting)."""
    return (1.0 - e**2) / (1.0 + e * jnp.sin(jnp.deg2rad(omega)))

