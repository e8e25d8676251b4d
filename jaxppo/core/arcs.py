"""Integrals along circle arcs parametrised by the angle tau from the
circle's near point (the point closest to the stellar centre): the one
numerical step of the exact occultation kernels (``jaxppo.core.occult``)."""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array

from .geometry import cos_sin

__all__ = ["half_angle_nodes", "arc_integrals"]


def half_angle_nodes(start: Array, span: Array, u: Array) -> tuple[Array, Array]:
    """sin and cos of tau / 2 at tau = start + span u (nodes u on a trailing
    axis, |span| <= pi): one sin and cos per piece, polynomials per node.
    Half angles keep full relative precision for tau -> 0, where the arc of a
    huge circle crosses the star."""
    a = 0.5 * start
    cu, su = cos_sin(0.5 * span[..., None] * u)
    sa, ca = jnp.sin(a)[..., None], jnp.cos(a)[..., None]
    return sa * cu + ca * su, ca * cu - sa * su


def arc_integrals(g, intensity, start, span, dm2, pd, ppd, rule, dtype, shape: bool, lin=None):
    """Integrals over arcs [start, start + span] of circles parametrised by the
    angle tau from their *near* point (the point closest to the stellar
    centre), where

        r^2 = (d - p)^2 + 4 p d sin^2(tau / 2),
        x dy - y dx = (p (p - d) + 2 p d sin^2(tau / 2)) dtau

    (no cancellation for huge circles, d ~ p >> 1, nor for circles through the
    centre, d ~ p). ``dm2`` = (d - p)^2, ``pd`` = p d, ``ppd`` = p (p - d),
    broadcasting against ``start``. Returns the Green's-theorem integral of each arc
    and, with ``shape``, the integrals of I cos tau, I sin tau and I over it
    (for the shape derivative, see ``union_deficit``).

    ``lin`` = (p a, p b), optional, adds p (a cos tau + b sin tau) to
    x dy - y dx and twice that to r^2: the terms p c.n of a centre c moved
    by (a, b) along (e, e_perp). Callers pass a zero-valued (a, b) whose
    derivatives are those of the centre where polar coordinates about the
    stellar centre are singular (d = 0), so that second derivatives there
    are right; the values are unchanged."""
    u, w = rule
    u, w = jnp.asarray(u, dtype), jnp.asarray(w, dtype)
    sh, ch = half_angle_nodes(start, span, u)
    sh2 = sh * sh
    s = dm2[..., None] + 4.0 * pd[..., None] * sh2
    green = ppd[..., None] + 2.0 * pd[..., None] * sh2
    if lin is not None:
        cn = lin[0][..., None] * (1.0 - 2.0 * sh2) + lin[1][..., None] * (2.0 * sh * ch)
        s, green = s + 2.0 * cn, green + cn
    val = ((g(s) * green) @ w) * span
    if not shape:
        return val, None
    inten = intensity(s)
    return val, tuple((inten * f) @ w * span for f in (1.0 - 2.0 * sh2, 2.0 * sh * ch, 1.0))
