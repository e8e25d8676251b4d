"""Exact occultation of a radially symmetric star by any number of opaque disks.

Method (one frame, K disks)
---------------------------
The occulted region is R = (union of the disks) intersected with the stellar
disk. For a radially symmetric intensity I(r), Green's theorem with the vector
field g(r^2) (-y, x), g = Phi(r) / r^2 and Phi(r) = int_0^r s I(s) ds, gives

    int_R I dA = contour integral over the boundary of R of g(r^2) (x dy - y dx).

The boundary of R consists of

* arcs of each planet's circle that lie inside the star and outside every other
  disk: on a circle of radius p about (xc, yc) at angle t from the direction of
  its centre, r^2 = d^2 + p^2 + 2 p d cos t and x dy - y dx = (p^2 + p d cos t) dt;
* arcs of the stellar limb (r = 1) inside some disk: they contribute
  Phi(1) times their angle, exactly.

Phi is closed form for every profile (``jaxppo.core.intensity``), so the only
numerical step is a 1D integral of a smooth function along circle arcs. Each
circle is cut at its crossings with the other circles and the limb, and at the
points nearest to and farthest from the stellar centre; every piece is tested
at its midpoint and integrated with a Gauss-Legendre rule mapped so that nodes
cluster (like u^4) at both ends, where a limb crossing puts the intensity's
mu^q branch point. The result converges spectrally for
polynomial, non-linear and power-2 laws. Overlaps between disks are handled
exactly: nothing is added twice (unlike summing single-disk deficits), nested,
tangent, concentric and identical disks included.
"""

from __future__ import annotations

from typing import Callable

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .geometry import circle_intersection_angles, float_dtype, safe_atan2, safe_hypot
from .quadrature import clustered_rule, gauss_legendre_01

__all__ = ["union_deficit", "disk_deficit", "inner_disk_deficit", "inner_pair_deficit", "INNER_MARGIN", "INNER_ORDER"]

_TWO_PI = 2.0 * np.pi


def _duplicates(x: Array, y: Array, r: Array, tol: float) -> Array:
    """True for disk k when an earlier disk j < k is the same disk (within tol),
    or when its radius is not positive: such disks add nothing to the union."""
    k = x.shape[-1]
    same = (
        (jnp.abs(x[:, None] - x[None, :]) <= tol)
        & (jnp.abs(y[:, None] - y[None, :]) <= tol)
        & (jnp.abs(r[:, None] - r[None, :]) <= tol)
    )
    earlier = np.tril(np.ones((k, k), dtype=bool), -1)  # [k, j] with j < k
    return jnp.any(same & earlier, axis=-1) | (r <= 0)


def union_deficit(
    x: Float[Array, " disk"],
    y: Float[Array, " disk"],
    r: Float[Array, " disk"],
    g: Callable[[Array], Array],
    phi1: Array,
    order: int = 24,
) -> Array:
    """Integral of I over (union of disks) intersected with the unit disk.

    Args:
        x, y, r: centres and radii of the K disks [R*], one frame.
        g: s -> Phi(sqrt(s)) / s for s = r^2 in [0, 1] (``jaxppo.core.intensity``).
        phi1: Phi(1) = F0 / (2 pi).
        order: Gauss-Legendre nodes per arc piece.

    Returns:
        The occulted flux in the units of F0 (divide by F0 for a relative deficit).
    """
    dtype = float_dtype(x, y, r)
    x, y, r = (jnp.asarray(v, dtype) for v in (x, y, r))
    k = x.shape[-1]
    active = ~_duplicates(x, y, r, 64 * float(jnp.finfo(dtype).eps))

    # ---- planet circles: cut at crossings with the other disks and the limb --
    d = safe_hypot(x, y)
    t_far = safe_atan2(y, x)  # direction of the point farthest from the centre
    others = np.array([[j for j in range(k) if j != i] for i in range(k)], dtype=int).reshape(k, k - 1)
    zeros, ones = jnp.zeros((k, 1), dtype), jnp.ones((k, 1), dtype)
    ox = jnp.concatenate([x[others], zeros], axis=1)
    oy = jnp.concatenate([y[others], zeros], axis=1)
    oq = jnp.concatenate([r[others], ones], axis=1)
    o_active = jnp.concatenate([active[others], jnp.ones((k, 1), bool)], axis=1)
    base, half, crosses, nested = circle_intersection_angles(
        x[:, None], y[:, None], r[:, None], ox, oy, oq
    )
    # A circle that does not cross disk j lies wholly inside it or wholly
    # outside: decide by nesting, never by a test point that could sit on a
    # tangency. (For the star, "inside" means the circle is on the star.)
    crosses = crosses & o_active
    nested = nested & o_active
    nested_planet, on_star = nested[:, :-1], nested[:, -1]

    rel = base - t_far[:, None]
    a_lo = jnp.where(crosses, jnp.mod(rel - half, _TWO_PI), 0.0)
    a_hi = jnp.where(crosses, jnp.mod(rel + half, _TWO_PI), 0.0)
    # Cuts measured from the far point (0 = 2 pi); the near point is pi; cuts
    # of circles that do not cross sit on the far point.
    cuts = jnp.sort(jnp.concatenate([a_lo, a_hi, jnp.full((k, 1), np.pi, dtype)], axis=1), axis=1)
    starts = jnp.concatenate([zeros, cuts], axis=1)
    ends = jnp.concatenate([cuts, jnp.full((k, 1), _TWO_PI, dtype)], axis=1)

    # Which pieces bound the union. Circle k lies inside a crossing disk j on
    # exactly the arc base_j -/+ half_j, whose ends are cut points, so testing
    # the piece midpoint's *angle* against that arc is consistent with the cuts
    # even for slivers at near-tangency (a distance test there could drop one
    # side of a sliver, an O(length) error in a contour integral).
    mid = 0.5 * (starts + ends)
    off = jnp.abs(jnp.mod(mid[:, :, None] - rel[:, None, :] + np.pi, _TWO_PI) - np.pi)
    inside_arc = off < half[:, None, :]
    in_star = jnp.where(crosses[:, None, -1], inside_arc[:, :, -1], on_star[:, None])
    covered = jnp.where(crosses[:, None, :-1], inside_arc[:, :, :-1], nested_planet[:, None, :])
    keep = in_star & ~jnp.any(covered, axis=-1) & active[:, None] & (ends > starts)

    # Every piece gets nodes clustered like u^4 at both ends: at a limb
    # crossing (and at a planet-planet crossing that lies near the limb) the
    # intensity's mu^q branch point sits at the end of the piece.
    nodes, weights = clustered_rule(order)
    u = jnp.asarray(nodes, dtype)
    w = jnp.asarray(weights, dtype)
    span = (ends - starts)[..., None]
    t = starts[..., None] + span * u
    pd_cos = (r * d)[:, None, None] * jnp.cos(t)
    p2 = (r * r)[:, None, None]
    s = (d * d)[:, None, None] + p2 + 2.0 * pd_cos
    pieces = jnp.sum(g(s) * (p2 + pd_cos) * w, axis=-1) * (ends - starts)
    planet_part = jnp.sum(jnp.where(keep, pieces, 0.0))

    # ---- stellar limb: arcs inside some disk contribute Phi(1) d(angle) ------
    lbase, lhalf, lcross, star_in_disk = circle_intersection_angles(0.0, 0.0, 1.0, x, y, r)
    lcross = lcross & active
    l_lo = jnp.where(lcross, jnp.mod(lbase - lhalf, _TWO_PI), 0.0)
    l_hi = jnp.where(lcross, jnp.mod(lbase + lhalf, _TWO_PI), 0.0)
    lcuts = jnp.sort(jnp.concatenate([l_lo, l_hi]))
    lstart = jnp.concatenate([jnp.zeros(1, dtype), lcuts])
    lend = jnp.concatenate([lcuts, jnp.full(1, _TWO_PI, dtype)])
    lmid = 0.5 * (lstart + lend)
    loff = jnp.abs(jnp.mod(lmid[:, None] - lbase[None, :] + np.pi, _TWO_PI) - np.pi)
    in_disk = jnp.where(lcross, loff < lhalf, star_in_disk & active)
    limb_angle = jnp.sum(jnp.where(jnp.any(in_disk, axis=-1), lend - lstart, 0.0))

    return planet_part + phi1 * limb_angle


def disk_deficit(
    d: Array, p: Array, g: Callable[[Array], Array], phi1: Array, order: int = 24
) -> Array:
    """Occulted flux of one disk of radius ``p`` whose centre is ``d`` from the
    stellar centre (a single-disk scene depends on nothing else).

    The circle's integrand depends on the angle t from its far point only
    through cos t, so the arc inside the star, [t_c, 2 pi - t_c], is twice
    [t_c, pi]: one mapped Gauss-Legendre piece, clustered at the limb crossing
    t_c and at the near point pi.
    """
    dtype = float_dtype(d, p)
    d, p = jnp.asarray(d, dtype), jnp.asarray(p, dtype)
    # Limb crossing seen from the planet's centre (angle from the far point,
    # i.e. from the direction away from the star) and from the star's centre.
    _, half_p, crosses, on_star = circle_intersection_angles(d, 0.0, p, 0.0, 0.0, 1.0)
    _, half_s, _, covers = circle_intersection_angles(0.0, 0.0, 1.0, d, 0.0, p)
    t_c = jnp.where(crosses, np.pi - half_p, 0.0)
    inside = on_star | crosses
    nodes, weights = clustered_rule(order)
    u = jnp.asarray(nodes, dtype)
    w = jnp.asarray(weights, dtype)
    span = np.pi - t_c
    t = t_c + span * u
    pd_cos = p * d * jnp.cos(t)
    s = d * d + p * p + 2.0 * pd_cos
    arc = 2.0 * span * jnp.sum(w * g(s) * (p * p + pd_cos), axis=-1)
    limb = jnp.where(crosses, 2.0 * half_s, 0.0)
    out = jnp.where(inside & ~covers, arc + phi1 * limb, 0.0)
    return jnp.where(covers, 2.0 * np.pi * phi1, out)


# A disk with 1 - d - p >= INNER_MARGIN * p is far enough from the limb that
# its integrand, an analytic even function of t, is integrated to ~1e-15 by
# the midpoint rule with INNER_ORDER nodes on [0, pi] (geometric convergence
# of the trapezoid rule for periodic integrands; measured in tests/test_occult.py).
INNER_MARGIN = 1.0
INNER_ORDER = 8


def inner_disk_deficit(d: Array, p: Array, g: Callable[[Array], Array], order: int = INNER_ORDER) -> Array:
    """Occulted flux of one disk lying wholly on the star, away from the limb
    (1 - d - p >= INNER_MARGIN p): the midpoint rule over its whole circle,
    2 pi / n sum_j f(cos t_j), t_j = (j + 1/2) pi / n."""
    dtype = float_dtype(d, p)
    d, p = jnp.asarray(d, dtype), jnp.asarray(p, dtype)
    t = jnp.asarray((np.arange(order) + 0.5) * np.pi / order, dtype)
    pd_cos = (p * d)[..., None] * jnp.cos(t)
    s = (d * d + p * p)[..., None] + 2.0 * pd_cos
    return (2.0 * np.pi / order) * jnp.sum(g(s) * ((p * p)[..., None] + pd_cos), axis=-1)


def inner_pair_deficit(
    x: Array, y: Array, r: Array, g: Callable[[Array], Array], order: int = INNER_ORDER, lens_order: int = 12
) -> Array:
    """Occulted flux of two overlapping disks that both lie well inside the star
    (1 - d - p >= INNER_MARGIN p for each), by inclusion-exclusion:
    D(A u B) = D(A) + D(B) - D(A n B). The full circles take the midpoint
    rule; the lens is bounded by the arc of A inside B and the arc of B inside
    A, smooth away from the limb, each integrated by Gauss-Legendre. Nested
    disks reduce to the larger one. ``x, y, r`` have a last axis of length 2.
    """
    dtype = float_dtype(x, y, r)
    x, y, r = (jnp.asarray(v, dtype) for v in (x, y, r))
    d = safe_hypot(x, y)
    full = inner_disk_deficit(d, r, g, order)  # [..., 2]
    u, w = gauss_legendre_01(lens_order)
    u, w = jnp.asarray(u, dtype), jnp.asarray(w, dtype)

    def arc(i, j):
        base, half, crosses, inside = circle_intersection_angles(x[..., i], y[..., i], r[..., i], x[..., j], y[..., j], r[..., j])
        t = (base - half)[..., None] + (2.0 * half)[..., None] * u
        p = r[..., i][..., None]
        proj = x[..., i][..., None] * jnp.cos(t) + y[..., i][..., None] * jnp.sin(t)
        s = (d[..., i] ** 2)[..., None] + p * p + 2.0 * p * proj
        val = 2.0 * half * jnp.sum(w * g(s) * (p * p + p * proj), axis=-1)
        return jnp.where(crosses, val, 0.0), crosses, inside

    a01, crosses, inside01 = arc(0, 1)
    a10, _, inside10 = arc(1, 0)
    lens = a01 + a10
    union = full[..., 0] + full[..., 1] - lens
    nested = jnp.where(inside01, full[..., 1], jnp.where(inside10, full[..., 0], full[..., 0] + full[..., 1]))
    return jnp.where(crosses, union, nested)
