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

from .geometry import circle_intersection_angles, cos_sin, float_dtype, heron_product, safe_atan2, safe_hypot, safe_sqrt
from .quadrature import clustered_rule, gauss_legendre_01

__all__ = ["union_deficit", "disk_deficit", "inner_disk_deficit", "lens_deficit", "lens_rho",
           "INNER_MARGIN", "INNER_ORDER", "LENS_ORDER", "LENS_RULES"]

_TWO_PI = 2.0 * np.pi


def node_sum(rule: tuple[np.ndarray, np.ndarray], f: Callable[[Array], Array], dtype) -> Array:
    """sum_j w_j f(u_j) over a static rule, as a product with the weight
    vector: f is evaluated on the nodes along a trailing axis (one vectorised
    elementwise loop) and contracted by a matrix-vector product. XLA's CPU
    code for a sum over a short trailing axis is not vectorised and costs
    about twice as much; unrolling the sum is as fast but compiles gradients
    three times slower."""
    u, w = rule
    return f(jnp.asarray(u, dtype)) @ jnp.asarray(w, dtype)


def _circle_term(g: Callable[[Array], Array], cos_t: Array, pd: Array, c0: Array, p2: Array) -> Array:
    """Green's-theorem integrand on a circle of radius p whose centre is d from
    the stellar centre, at angle t from its far point:
    g(r^2) (p^2 + p d cos t), r^2 = d^2 + p^2 + 2 p d cos t."""
    pd_cos = pd * cos_t
    return g(c0 + 2.0 * pd_cos) * (p2 + pd_cos)


def _arc_cos(t0: Array, span: Array, u: Array) -> Array:
    """cos(t0 + span u) at the nodes u (trailing axis) of an arc with
    |span u| <= pi: one cos and sin per arc, polynomials per node."""
    cu, su = cos_sin(span[..., None] * u)
    return jnp.cos(t0)[..., None] * cu - jnp.sin(t0)[..., None] * su


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
    span = ends - starts
    pd = (r * d)[:, None, None]
    p2 = (r * r)[:, None, None]
    c0 = p2 + (d * d)[:, None, None]
    # pieces end at the far (0, 2 pi) and near (pi) points: spans <= pi
    pieces = node_sum(clustered_rule(order), lambda u: _circle_term(g, _arc_cos(starts, span, u), pd, c0, p2), dtype) * span
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
    span = np.pi - t_c
    pd, c0, p2 = (p * d)[..., None], (d * d + p * p)[..., None], (p * p)[..., None]
    arc = 2.0 * span * node_sum(clustered_rule(order), lambda u: _circle_term(g, _arc_cos(t_c, span, u), pd, c0, p2), dtype)
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
    pd, c0, p2 = (p * d)[..., None], (d * d + p * p)[..., None], (p * p)[..., None]
    # the rule's "nodes" are the cosines themselves: constants
    rule = (np.cos((np.arange(order) + 0.5) * np.pi / order), np.full(order, 2.0 * np.pi / order))
    return node_sum(rule, lambda cos_t: _circle_term(g, cos_t, pd, c0, p2), dtype)


# Gauss-Legendre nodes per lens arc, and the smallest Bernstein-ellipse
# parameter (``lens_rho``: of the integrand's branch point on the limb, seen
# from the arc) at which "auto" uses them: the error ~rho^(-2 n) is below
# ~3e-14 of the stellar flux at every tier (measured in tests/test_occult.py;
# 8 nodes at rho >= 6, 12 at rho >= 3, 16 at rho >= 2). Lenses with rho < 2
# (at or next to the limb) take the union integral.
LENS_RULES = ((8, 6.0), (12, 3.0), (16, 2.0))
LENS_ORDER = 12


def lens_deficit(x: Array, y: Array, r: Array, g: Callable[[Array], Array], order: int = LENS_ORDER) -> Array:
    """Integral of I over the lens A n B of two crossing disks that lies wholly
    on the star (``x, y, r`` have a last axis of length 2; 0 where the circles
    do not cross).

    The lens is bounded by the arc of A inside B and the arc of B inside A,
    both traversed counter-clockwise about their own centres. The two arcs
    share their end points, so one Heron product gives both half-widths. On
    circle A (centre at distance d, angle phi_A) the radius of a boundary point
    is s = d^2 + p^2 + 2 p d cos(t - phi_A); the node cosines come from
    ``_arc_cos`` (one cos and sin per arc, polynomials per node).
    """
    dtype = float_dtype(x, y, r)
    x, y, r = (jnp.asarray(v, dtype) for v in (x, y, r))
    xa, ya, pa, xb, yb, pb = x[..., 0], y[..., 0], r[..., 0], x[..., 1], y[..., 1], r[..., 1]
    dx, dy = xb - xa, yb - ya
    delta = safe_hypot(dx, dy)
    base = safe_atan2(dy, dx)  # direction A -> B, seen from A
    prod = heron_product(pa, delta, pb)
    crosses = (prod > 0) & (delta > 0)
    sq = safe_sqrt(jnp.where(crosses, prod, 0.0))
    rule = gauss_legendre_01(order)

    def arc(cx, cy, p, q, centre):
        half = jnp.arctan2(sq, jnp.where(crosses, (p - q) * (p + q) + delta * delta, 1.0))
        d = safe_hypot(cx, cy)
        mid = centre - safe_atan2(cy, cx)  # arc centre, from the far point
        pd, c0, p2 = (p * d)[..., None], (d * d + p * p)[..., None], (p * p)[..., None]
        return 2.0 * half * node_sum(rule, lambda v: _circle_term(g, _arc_cos(mid, half, 2.0 * v - 1.0), pd, c0, p2), dtype)

    lens = arc(xa, ya, pa, pb, base) + arc(xb, yb, pb, pa, base + np.pi)
    return jnp.where(crosses, lens, 0.0)


def lens_rho(x: Array, y: Array, r: Array) -> Array:
    """How fast ``lens_deficit`` converges for a crossing pair (last axis of
    length 2): the smaller, over the two lens arcs, Bernstein-ellipse parameter
    rho of the integrand's branch point s = 1 (the stellar limb) seen from the
    arc; n nodes err like rho^(-2n). 1 where the lens reaches the limb or
    lies off the star, or the disks do not cross.

    On circle A (centre at distance d, radius p) s = 1 where
    cos(t - phi_A) = c = (1 - d^2 - p^2) / (2 p d), phi_A the direction of A's
    far point: at t = phi_A +/- i acosh(c) for a circle inside the star, at
    real t = phi_A +/- acos(c) for one that crosses the limb. Mapping the lens
    arc (centre: the direction to the other disk; half-width h) to [-1, 1], a
    singular point z lies on the ellipse with foci -/+1 and semi-major axis
    a = (|z - 1| + |z + 1|) / 2, and rho = a + sqrt(a^2 - 1).
    """
    dtype = float_dtype(x, y, r)
    x, y, r = (jnp.asarray(v, dtype) for v in (x, y, r))
    dx, dy = x[..., 1] - x[..., 0], y[..., 1] - y[..., 0]
    delta2 = dx * dx + dy * dy
    prod = heron_product(r[..., 0], safe_sqrt(delta2), r[..., 1])
    crosses = prod > 0
    sq = safe_sqrt(prod)

    def wrap(a):
        return jnp.mod(a + np.pi, _TWO_PI) - np.pi

    rho = jnp.full(prod.shape, jnp.inf, dtype)
    for i, sign in ((0, 1.0), (1, -1.0)):
        p, q, cx, cy = r[..., i], r[..., 1 - i], x[..., i], y[..., i]
        ux, uy = sign * dx, sign * dy  # towards the other centre
        half = jnp.maximum(jnp.arctan2(sq, (p - q) * (p + q) + delta2), jnp.finfo(dtype).tiny)
        d2 = cx * cx + cy * cy
        pd = p * jnp.sqrt(d2)
        c = (1.0 - d2 - p * p) / jnp.where(pd > 0, 2.0 * pd, 1.0)
        off = safe_atan2(ux * cy - uy * cx, ux * cx + uy * cy)  # far point, from the arc centre
        root = jnp.sqrt(jnp.abs(c * c - 1.0))
        # c >= 1: singular points off +/- i acosh(c); -1 < c < 1: real points
        # off +/- acos(c), of which the nearer to the arc centre decides
        tau = jnp.log(jnp.maximum(c, 1.0) + root)
        ac = jnp.arctan2(root, jnp.clip(c, -1.0, 1.0))
        z_re = jnp.where(c >= 1.0, jnp.abs(off), jnp.minimum(jnp.abs(wrap(off + ac)), jnp.abs(wrap(off - ac)))) / half
        z_im = jnp.where(c >= 1.0, tau, 0.0) / half
        a = 0.5 * (jnp.sqrt((z_re - 1.0) ** 2 + z_im * z_im) + jnp.sqrt((z_re + 1.0) ** 2 + z_im * z_im))
        arc = jnp.where(c > -1.0, a + jnp.sqrt(jnp.maximum(a * a - 1.0, 0.0)), 1.0)
        rho = jnp.minimum(rho, jnp.where(pd > 0, arc, jnp.inf))
    # A lens corner must lie on the star, or the whole lens is off it. The
    # corner is c0 + [u (p^2 - q^2 + delta^2) + u_perp sq] / (2 delta^2).
    scale = 0.5 / jnp.where(crosses, delta2, 1.0)
    cos_term = (r[..., 0] - r[..., 1]) * (r[..., 0] + r[..., 1]) + delta2
    kx = x[..., 0] + scale * (dx * cos_term - dy * sq)
    ky = y[..., 0] + scale * (dy * cos_term + dx * sq)
    return jnp.where(crosses & (kx * kx + ky * ky < 1.0), rho, 1.0)
