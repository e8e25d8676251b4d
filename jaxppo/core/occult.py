"""Exact occultation of a radially symmetric star by any number of opaque disks.

Method (one frame, K disks)
---------------------------
The occulted region is R = (union of the disks) intersected with the stellar
disk. For a radially symmetric intensity I(r), Green's theorem with the vector
field g(r^2) (-y, x), g = Phi(r) / r^2 and Phi(r) = int_0^r s I(s) ds, gives

    int_R I dA = contour integral over the boundary of R of g(r^2) (x dy - y dx).

The boundary of R consists of

* arcs of each planet's circle that lie inside the star and outside every other
  disk: on a circle of radius p whose centre is d from the stellar centre, at
  angle tau from its near point, r^2 = (d - p)^2 + 4 p d sin^2(tau/2) and
  x dy - y dx = (p (p - d) + 2 p d sin^2(tau/2)) dtau (``union_deficit``,
  ``disk_deficit``; the lens and midpoint rules of "auto" use the cosine
  about the far point, r^2 = d^2 + p^2 + 2 p d cos t, for disks no larger
  than the star);
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
tangent, concentric and identical disks included. Derivatives with respect to
the disks are shape derivatives (a custom JVP; see ``union_deficit``).
"""

from __future__ import annotations

import functools
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .geometry import (
    circle_intersection_angles,
    cos_sin,
    crossing_half_width,
    float_dtype,
    heron_product,
    safe_atan2,
    safe_hypot,
    safe_sqrt,
    wrap_angle,
)
from .arcs import arc_integrals
from .centre import CENTRED_D
from .quadrature import clustered_rule, gauss_legendre_01

__all__ = ["MAX_RADIUS", "union_deficit", "disk_deficit", "inner_disk_deficit", "lens_deficit", "lens_rho",
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


# Largest disk radius [R*] the kernels accept. Arcs of huge circles are
# integrated from their near point without cancellation, so what remains is
# the rounding of the disk's distance from the star (one ulp of d ~ R moves
# the disk by ~1e-16 R): below 1e-10 of the stellar flux up to R = 1e6
# (measured in tests/core/test_occult.py). Larger radii are refused.
MAX_RADIUS = 1e6


def _bad_input(*arrays) -> Array:
    """True when a value is not finite or a radius (the last array) is
    negative or above MAX_RADIUS: traced bad input gives NaN, never a
    plausible flux."""
    ok = jnp.all(jnp.stack([jnp.all(jnp.isfinite(a)) for a in arrays]))
    return ~(ok & jnp.all(arrays[-1] >= 0) & jnp.all(arrays[-1] <= MAX_RADIUS))


def _intensity_from_g(g: Callable[[Array], Array]) -> Callable[[Array], Array]:
    """I(s) = 2 d(s g)/ds for callers that give g only (less accurate at the
    limb than the profile itself, where dg/ds has a removable singularity)."""

    def intensity(s):
        val, dg = jax.jvp(g, (s,), (jnp.ones_like(s),))
        return 2.0 * (val + s * dg)

    return intensity


def _planet_pieces(x, y, r, active):
    """The planet circles of one frame cut at their crossings with the other
    disks and the limb: (d, ex, ey, starts, ends, keep), with ``keep`` the
    pieces [disk, piece] that bound the union (inside the star, outside
    every other disk)."""
    dtype = x.dtype
    k = x.shape[-1]
    # Each circle's angle tau is measured from its near point, direction e
    # (towards the stellar centre; +x for a circle centred on it).
    d_true = safe_hypot(x, y)
    # a centre within CENTRED_D of the star's (its circle off the limb) is
    # measured from e = +x (see ``_union_parts``): its polar d is 0
    centred = (d_true < CENTRED_D) & (jnp.abs(1.0 - r) > CENTRED_D)
    d = jnp.where(centred, 0.0, d_true)
    has_dir = d > 0
    d_safe = jnp.where(has_dir, d, 1.0)
    ex = jnp.where(has_dir, -x / d_safe, 1.0)
    ey = jnp.where(has_dir, -y / d_safe, 0.0)
    others = np.array([[j for j in range(k) if j != i] for i in range(k)], dtype=int).reshape(k, k - 1)
    ddx, ddy = x[others] - x[:, None], y[others] - y[:, None]
    # direction of every other centre seen from this one, in the circle's frame;
    # the star's centre is at tau = 0 by definition
    base = jnp.concatenate(
        [safe_atan2(ex[:, None] * ddy - ey[:, None] * ddx, ex[:, None] * ddx + ey[:, None] * ddy), jnp.zeros((k, 1), dtype)],
        axis=1,
    )
    delta = jnp.concatenate([safe_hypot(ddx, ddy), d_true[:, None]], axis=1)
    oq = jnp.concatenate([r[others], jnp.ones((k, 1), dtype)], axis=1)
    o_active = jnp.concatenate([active[others], jnp.ones((k, 1), bool)], axis=1)
    half, crosses, nested = crossing_half_width(r[:, None], delta, oq)
    # A circle that does not cross disk j lies wholly inside it or wholly
    # outside: decide by nesting, never by a test point that could sit on a
    # tangency. (For the star, "inside" means the circle is on the star.)
    crosses = crosses & o_active
    nested = nested & o_active
    nested_planet, on_star = nested[:, :-1], nested[:, -1]
    # A circle that *is* the limb bounds the union once, as the limb (it
    # would otherwise count both as a planet circle on the star and as a disk
    # covering the star).
    is_limb = (d_true == 0) & (r == 1)

    lo = jnp.where(crosses, wrap_angle(base - half), 0.0)
    hi = jnp.where(crosses, wrap_angle(base + half), 0.0)
    # Cuts in (-pi, pi]; the near point (0) is one, the far point (-/+ pi)
    # bounds the range: pieces span at most pi. Cuts of circles that do not
    # cross sit on the near point.
    cuts = jnp.sort(jnp.concatenate([lo, hi, jnp.zeros((k, 1), dtype)], axis=1), axis=1)
    starts = jnp.concatenate([jnp.full((k, 1), -np.pi, dtype), cuts], axis=1)
    ends = jnp.concatenate([cuts, jnp.full((k, 1), np.pi, dtype)], axis=1)

    # Which pieces bound the union. Circle k lies inside a crossing disk j on
    # exactly the arc base_j -/+ half_j, whose ends are cut points, so testing
    # the piece midpoint's *angle* against that arc is consistent with the cuts
    # even for slivers at near-tangency (a distance test there could drop one
    # side of a sliver, an O(length) error in a contour integral).
    mid = 0.5 * (starts + ends)
    off = jnp.abs(wrap_angle(mid[:, :, None] - base[:, None, :]))
    inside_arc = off < half[:, None, :]
    in_star = jnp.where(crosses[:, None, -1], inside_arc[:, :, -1], on_star[:, None])
    covered = jnp.where(crosses[:, None, :-1], inside_arc[:, :, :-1], nested_planet[:, None, :])
    keep = in_star & ~jnp.any(covered, axis=-1) & (active & ~is_limb)[:, None] & (ends > starts)
    return d, centred, ex, ey, starts, ends, keep


def _limb_angle(x, y, r, active):
    """The angle [rad] of the stellar limb inside some disk (those arcs
    contribute Phi(1) d(angle) to the union integral)."""
    dtype = x.dtype
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
    return jnp.sum(jnp.where(jnp.any(in_disk, axis=-1), lend - lstart, 0.0))


def _union_parts(x, y, r, g, intensity, phi1, order: int, shape: bool):
    """The union integral of one frame (see ``union_deficit``), and with
    ``shape`` the shape derivatives (dF/dx, dF/dy, dF/dr) of every disk."""
    dtype = x.dtype
    active = ~_duplicates(x, y, r, 64 * float(jnp.finfo(dtype).eps))
    d, centred, ex, ey, starts, ends, keep = _planet_pieces(x, y, r, active)
    # Every piece gets nodes clustered like u^4 at both ends: at a limb
    # crossing (and at a planet-planet crossing that lies near the limb) the
    # intensity's mu^q branch point sits at the end of the piece.
    dm = d - r
    # Near d = 0 the polar coordinates (d, e) of a centre are singular: at
    # d = 0 the guards give d and e zero derivatives (every second
    # derivative in the centre was 0), and just off it the curvature across
    # e, F'(d) / d, loses ~eps / d of its digits (2x at d = 1e-15, which
    # cos(90 deg) gives). There (``_planet_pieces``: d < CENTRED_D, not on
    # the limb) the circle is measured from the fixed direction e = +x, at
    # d = 0 in the polar terms, and the centre enters r^2 = |c + p n|^2
    # exactly: |c|^2 and c.n = x cos tau + y sin tau.
    cx, cy = jnp.where(centred, x, 0.0), jnp.where(centred, y, 0.0)
    vals, moments = arc_integrals(
        g, intensity, starts, ends - starts, (dm * dm + cx * cx + cy * cy)[:, None], (r * d)[:, None],
        (-r * dm)[:, None], clustered_rule(order), dtype, shape, lin=((r * cx)[:, None], (r * cy)[:, None]),
    )
    planet_part = jnp.sum(jnp.where(keep, vals, 0.0))
    limb_angle = _limb_angle(x, y, r, active)

    bad = _bad_input(x, y, r)
    value = jnp.where(bad, jnp.nan, planet_part + phi1 * limb_angle)
    if not shape:
        return value, None
    # Shape derivative: moving disk k moves only its kept arcs, each point
    # with the disk's velocity, so dF = sum over its arcs of I (v . n) ds with
    # n = e cos tau + e_perp sin tau, ds = p dtau. No term comes from where
    # the arcs end, so nothing depends on how slivers at triple points or at
    # crossings on the limb were classified.
    ic, is_, i0 = (jnp.sum(jnp.where(keep, m, 0.0), axis=-1) for m in moments)
    r = jnp.where(bad, jnp.nan, r)  # bad input: NaN derivatives as well
    return value, (r * (ex * ic - ey * is_), r * (ey * ic + ex * is_), r * i0)


def _is_zero(t) -> bool:
    return isinstance(t, jax.custom_derivatives.SymbolicZero)


def _instantiate(t, like):
    return jnp.zeros(jnp.shape(like), jnp.result_type(like)) if _is_zero(t) else t


def _shape_jvp(parts, n_geom: int, primals, tangents, axis=None):
    """JVP from ``parts(*geometry, phi1, consts) -> (value, shape derivatives)``:
    the geometric tangents by the shape derivatives, the profile's (phi1 and
    the radial kernel's constants) by forward differentiation with the
    geometry held fixed (the domain does not move)."""
    geom, (phi1, consts) = primals[:n_geom], primals[n_geom:]
    tgeom, (tphi, tconsts) = tangents[:n_geom], tangents[n_geom:]
    diff = [i for i, c in enumerate(consts) if jnp.issubdtype(jnp.result_type(c), jnp.inexact)]

    def f(phi1, dconsts):
        full = list(consts)
        for i, c in zip(diff, dconsts):
            full[i] = c
        return parts(*geom, phi1, full)

    dconsts = [consts[i] for i in diff]
    if _is_zero(tphi) and all(_is_zero(tconsts[i]) for i in diff):
        value, derivs = f(phi1, dconsts)
        dvalue = jnp.zeros_like(value)
    else:
        value, dvalue, derivs = jax.jvp(
            f, (phi1, dconsts), (_instantiate(tphi, phi1), [_instantiate(tconsts[i], consts[i]) for i in diff]), has_aux=True
        )
    for t, dv in zip(tgeom, derivs):
        if not _is_zero(t):
            dvalue = dvalue + jnp.sum(dv * t, axis=axis)
    return value, dvalue.astype(value.dtype)


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2))
def _union_core(order, g_fn, i_fn, x, y, r, phi1, consts):
    g_consts, i_consts = consts
    return _union_parts(x, y, r, lambda s: g_fn(s, *g_consts), lambda s: i_fn(s, *i_consts), phi1, order, False)[0]


@_union_core.defjvp
def _union_core_jvp(order, g_fn, i_fn, primals, tangents):
    x, y, r, phi1, (g_consts, i_consts) = primals
    _, _, _, tphi, (tg, _) = tangents

    def parts(x, y, r, phi1, g_consts):
        return _union_parts(x, y, r, lambda s: g_fn(s, *g_consts), lambda s: i_fn(s, *i_consts), phi1, order, True)

    return _shape_jvp(parts, 3, (x, y, r, phi1, list(g_consts)), tuple(tangents[:3]) + (tphi, list(tg)))


def _convert(fn: Callable[[Array], Array], shape, dtype):
    """fn with the arrays it closes over made explicit (``jax.closure_convert``,
    for a custom JVP), for arguments of the given shape."""
    return jax.closure_convert(fn, jnp.zeros(shape, dtype))


def union_deficit(
    x: Float[Array, " disk"],
    y: Float[Array, " disk"],
    r: Float[Array, " disk"],
    g: Callable[[Array], Array],
    phi1: Array,
    order: int = 24,
    intensity: Callable[[Array], Array] | None = None,
) -> Array:
    """Integral of I over (union of disks) intersected with the unit disk.

    Args:
        x, y, r: centres and radii of the K disks [R*], one frame.
        g: s -> Phi(sqrt(s)) / s for s = r^2 in [0, 1] (``jaxppo.core.intensity``).
        phi1: Phi(1) = F0 / (2 pi).
        order: Gauss-Legendre nodes per arc piece.
        intensity: s -> I at r^2 = s, for the derivatives (default: from g).

    Returns:
        The occulted flux in the units of F0 (divide by F0 for a relative
        deficit); NaN when an input is not finite or a radius is negative.

    Derivatives with respect to the disks are the shape derivatives (each
    disk's arcs on the boundary of the region, moving with it): exact where
    the flux is differentiable, triple points and crossings on the limb
    included, and free of the cut points' own derivatives.
    """
    dtype = float_dtype(x, y, r)
    x, y, r = (jnp.asarray(v, dtype) for v in (x, y, r))
    k = x.shape[-1]
    if intensity is None:
        intensity = _intensity_from_g(g)
    shape = (k, 2 * k + 2, order)
    g_fn, g_consts = _convert(g, shape, dtype)
    i_fn, i_consts = _convert(intensity, shape, dtype)
    return _union_core(order, g_fn, i_fn, x, y, r, phi1, (tuple(g_consts), tuple(i_consts)))


def _disk_parts(d, p, g, intensity, phi1, order: int, shape: bool):
    """One disk's deficit (see ``disk_deficit``), with ``shape`` its shape
    derivatives (dF/dd, dF/dp)."""
    dtype = d.dtype
    # Half-widths of the planet's arc on the star, about its near point, and of
    # the limb's arc inside the planet.
    h_p, crosses, on_star = crossing_half_width(p, d, 1.0)
    h_s, _, covers = crossing_half_width(1.0, d, p)
    inside = (on_star | crosses) & ~covers
    span = jnp.where(crosses, h_p, np.pi)
    dm = d - p
    # the arc [-h, h] is symmetric about the near point: twice [0, h]
    vals, moments = arc_integrals(
        g, intensity, jnp.zeros_like(span), span, dm * dm, p * d, -p * dm, clustered_rule(order), dtype, shape
    )
    limb = jnp.where(crosses, 2.0 * h_s, 0.0)
    out = jnp.where(inside, 2.0 * vals + phi1 * limb, 0.0)
    out = jnp.where(covers, 2.0 * np.pi * phi1, out)
    bad = _bad_input(d, p)
    out = jnp.where(bad, jnp.nan, out)
    if not shape:
        return out, None
    ic, _, i0 = moments
    # e points at the stellar centre: moving away from it is -e
    p2 = jnp.where(bad, jnp.nan, 2.0 * p)
    return out, (jnp.where(inside, -p2 * ic, 0.0 * p2), jnp.where(inside, p2 * i0, 0.0 * p2))


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2))
def _disk_core(order, g_fn, i_fn, d, p, phi1, consts):
    g_consts, i_consts = consts
    return _disk_parts(d, p, lambda s: g_fn(s, *g_consts), lambda s: i_fn(s, *i_consts), phi1, order, False)[0]


@_disk_core.defjvp
def _disk_core_jvp(order, g_fn, i_fn, primals, tangents):
    d, p, phi1, (g_consts, i_consts) = primals
    _, _, tphi, (tg, _) = tangents

    def parts(d, p, phi1, g_consts):
        return _disk_parts(d, p, lambda s: g_fn(s, *g_consts), lambda s: i_fn(s, *i_consts), phi1, order, True)

    return _shape_jvp(parts, 2, (d, p, phi1, list(g_consts)), tuple(tangents[:2]) + (tphi, list(tg)))


def disk_deficit(
    d: Array, p: Array, g: Callable[[Array], Array], phi1: Array, order: int = 24,
    intensity: Callable[[Array], Array] | None = None,
) -> Array:
    """Occulted flux of one disk of radius ``p`` whose centre is ``d`` from the
    stellar centre (a single-disk scene depends on nothing else), one disk.

    The circle's arc on the star is symmetric about its near point: it is
    twice the arc [0, h] from the near point to the limb crossing (h = pi for
    a disk wholly on the star), one mapped Gauss-Legendre piece clustered at
    both ends. Derivatives are the shape derivatives (see ``union_deficit``).
    """
    dtype = float_dtype(d, p)
    d, p = jnp.asarray(d, dtype), jnp.asarray(p, dtype)
    if intensity is None:
        intensity = _intensity_from_g(g)
    shape = (order,)
    g_fn, g_consts = _convert(g, shape, dtype)
    i_fn, i_consts = _convert(intensity, shape, dtype)
    return _disk_core(order, g_fn, i_fn, d, p, phi1, (tuple(g_consts), tuple(i_consts)))


# A disk with 1 - d - p >= INNER_MARGIN * p is far enough from the limb that
# its integrand, an analytic even function of t, is integrated to ~1e-15 by
# the midpoint rule with INNER_ORDER nodes on [0, pi] (geometric convergence
# of the trapezoid rule for periodic integrands; measured in tests/core/test_occult.py).
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
# ~3e-14 of the stellar flux at every tier (measured in tests/core/test_occult.py;
# 8 nodes at rho >= 6, 12 at rho >= 3, 16 at rho >= 2). Lenses with rho < 2
# (at or next to the limb) take the union integral.
LENS_RULES = ((8, 6.0), (12, 3.0), (16, 2.0))
LENS_ORDER = 12


def _lens_parts(x, y, r, g, intensity, order: int, shape: bool):
    """The lens integral (see ``lens_deficit``) of [..., 2] arrays, and with
    ``shape`` its shape derivatives (dL/dx, dL/dy, dL/dr of both disks)."""
    dtype = x.dtype
    xa, ya, pa, xb, yb, pb = x[..., 0], y[..., 0], r[..., 0], x[..., 1], y[..., 1], r[..., 1]
    dx, dy = xb - xa, yb - ya
    delta = safe_hypot(dx, dy)
    prod = heron_product(pa, delta, pb)
    crosses = (prod > 0) & (delta > 0)
    sq = safe_sqrt(jnp.where(crosses, prod, 0.0))
    # direction A -> B as a unit vector: the arcs' angles enter only through
    # cosines and sines, so no atan2 but the half-widths' (cheaper under jit)
    dl = jnp.where(delta > 0, delta, 1.0)
    ux, uy = jnp.where(delta > 0, dx / dl, 1.0), dy / dl
    u, w = gauss_legendre_01(order)
    u = jnp.asarray(2.0 * u - 1.0, dtype)  # [-1, 1]
    w = jnp.asarray(w, dtype)

    def arc(cx, cy, p, q, cc, sc):
        """The arc of circle (cx, cy, p) centred on direction (cc, sc)."""
        half = jnp.arctan2(sq, jnp.where(crosses, (p - q) * (p + q) + delta * delta, 1.0))
        d = safe_hypot(cx, cy)
        ds = jnp.where(d > 0, d, 1.0)
        cf, sf = jnp.where(d > 0, cx / ds, 1.0), cy / ds  # the far point's direction
        # the arc centre seen from the far point: mid = centre - far
        cm, sm = cc * cf + sc * sf, sc * cf - cc * sf
        pd, c0, p2 = (p * d)[..., None], (d * d + p * p)[..., None], (p * p)[..., None]
        cu, su = cos_sin(half[..., None] * u)
        cos_t = cm[..., None] * cu - sm[..., None] * su
        val = 2.0 * half * ((_circle_term(g, cos_t, pd, c0, p2)) @ w)
        if not shape:
            return val, None
        # outward normal (cos th, sin th) at th = centre + half u: moving the
        # disk moves this arc only, dL = p int I (v . n) dth
        cc, sc = cc[..., None], sc[..., None]
        inten = intensity(c0 + 2.0 * pd * cos_t) * (2.0 * half * p)[..., None]
        return val, tuple((inten * f) @ w for f in (cc * cu - sc * su, sc * cu + cc * su, 1.0))

    va, ma = arc(xa, ya, pa, pb, ux, uy)
    vb, mb = arc(xb, yb, pb, pa, -ux, -uy)
    value = jnp.where(crosses, va + vb, 0.0)
    if not shape:
        return value, None
    return value, tuple(jnp.where(crosses[..., None], jnp.stack([a, b], -1), 0.0) for a, b in zip(ma, mb))


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2))
def _lens_core(order, g_fn, i_fn, x, y, r, phi1, consts):
    g_consts, i_consts = consts
    return _lens_parts(x, y, r, lambda s: g_fn(s, *g_consts), lambda s: i_fn(s, *i_consts), order, False)[0]


@_lens_core.defjvp
def _lens_core_jvp(order, g_fn, i_fn, primals, tangents):
    x, y, r, phi1, (g_consts, i_consts) = primals
    _, _, _, tphi, (tg, _) = tangents

    def parts(x, y, r, phi1, g_consts):
        return _lens_parts(x, y, r, lambda s: g_fn(s, *g_consts), lambda s: i_fn(s, *i_consts), order, True)

    # each lens is one value: its disks' tangents contract over the last axis
    return _shape_jvp(parts, 3, (x, y, r, phi1, list(g_consts)), tuple(tangents[:3]) + (tphi, list(tg)), axis=-1)


def lens_deficit(
    x: Array, y: Array, r: Array, g: Callable[[Array], Array], order: int = LENS_ORDER,
    intensity: Callable[[Array], Array] | None = None,
) -> Array:
    """Integral of I over the lens A n B of two crossing disks that lies wholly
    on the star (``x, y, r`` have a last axis of length 2; 0 where the circles
    do not cross).

    The lens is bounded by the arc of A inside B and the arc of B inside A,
    both traversed counter-clockwise about their own centres. The two arcs
    share their end points, so one Heron product gives both half-widths. On
    circle A (centre at distance d, angle phi_A) the radius of a boundary point
    is s = d^2 + p^2 + 2 p d cos(t - phi_A); the node cosines come from
    ``_arc_cos`` (one cos and sin per arc, polynomials per node).

    Derivatives with respect to the disks are the shape derivatives (each
    disk's arc moving with it, see ``union_deficit``): the derivatives of the
    parametrisation are wrong where it is singular (a disk centred on the
    star, equal radii at delta = p: ties in the Heron product).
    ``intensity`` (s -> I) is what they integrate (default: from g).
    """
    dtype = float_dtype(x, y, r)
    x, y, r = (jnp.asarray(v, dtype) for v in (x, y, r))
    if intensity is None:
        intensity = _intensity_from_g(g)
    shape = x.shape[:-1] + (order,)
    g_fn, g_consts = _convert(g, shape, dtype)
    i_fn, i_consts = _convert(intensity, shape, dtype)
    return _lens_core(order, g_fn, i_fn, x, y, r, jnp.zeros((), dtype), (tuple(g_consts), tuple(i_consts)))


def lens_rho(x: Array, y: Array, r: Array) -> Array:
    """How fast ``lens_deficit`` converges for a crossing pair (last axis of
    length 2): the smaller, over the two lens arcs, Bernstein-ellipse parameter
    rho of the integrand's branch point s = 1 (the stellar limb) seen from the
    arc; n nodes err like rho^(-2n). 1 where the lens reaches the limb or
    lies off the star, the disks do not cross, or one is larger than the star.

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
        # to (-pi, pi] for |a| < 3 pi; round is cheaper than mod under jit
        return a - _TWO_PI * jnp.round(a / _TWO_PI)

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
    # The lens rule parametrises arcs by their cosine about the far point,
    # which loses ~R^2 eps for a disk of radius R >> 1: lenses of disks larger
    # than the star take the union integral (arcs from the near point).
    small = jnp.maximum(r[..., 0], r[..., 1]) <= 1.0
    return jnp.where(crosses & small & (kx * kx + ky * ky < 1.0), rho, 1.0)
