"""Circle geometry with gradients that stay finite at contact points.

Kernels for one frame; callers vectorise. Every square root, arctangent and
division is guarded with the double-``where`` pattern so that tangent circles,
concentric circles and zero distances give finite values *and* finite
gradients.
"""

from __future__ import annotations

from math import factorial

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

__all__ = ["float_dtype", "safe_sqrt", "safe_atan2", "safe_hypot", "heron_product", "crossing_half_width",
           "circle_intersection_angles", "wrap_angle", "cos_sin"]


def float_dtype(*arrays):
    """The floating dtype of the inputs (float32 stays float32; integers and
    Python numbers give JAX's default float)."""
    dt = jnp.result_type(*arrays)
    return dt if jnp.issubdtype(dt, jnp.inexact) else jnp.result_type(float)


def safe_sqrt(x: ArrayLike) -> Array:
    """sqrt(max(x, 0)) with zero (not infinite) gradient at x <= 0."""
    x = jnp.asarray(x)
    pos = x > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def safe_hypot(x: ArrayLike, y: ArrayLike) -> Array:
    """sqrt(x^2 + y^2) to within 1 ulp, with a finite gradient everywhere.

    Where x^2 + y^2 would underflow into the subnormals or overflow it is
    scaled by max(|x|, |y|) (then the gradient stays (x, y) / hypot, not
    0 / 0), and the origin gives 0 with a zero gradient."""
    x, y = jnp.asarray(x), jnp.asarray(y)
    info = jnp.finfo(jnp.result_type(x, y, float) if not jnp.issubdtype(jnp.result_type(x, y), jnp.inexact) else jnp.result_type(x, y))
    sum2 = x * x + y * y
    plain = (sum2 >= float(info.tiny) / float(info.eps)) & (sum2 < float(info.max))
    m = jnp.maximum(jnp.abs(x), jnp.abs(y))
    zero = m == 0
    # hypot is homogeneous: the scale needs no derivative (its own would
    # divide by m^2, which underflows)
    ms = jax.lax.stop_gradient(jnp.where(zero | plain, 1.0, m))
    xs, ys = jnp.where(zero, 0.0, x) / ms, jnp.where(zero, 0.0, y) / ms
    scaled = jnp.where(zero, 0.0, ms * jnp.sqrt(xs * xs + ys * ys))
    return jnp.where(plain, jnp.sqrt(jnp.where(plain, sum2, 1.0)), scaled)


def safe_atan2(y: ArrayLike, x: ArrayLike) -> Array:
    """atan2 that returns 0 with zero gradient at (0, 0)."""
    y, x = jnp.asarray(y), jnp.asarray(x)
    zero = (x == 0) & (y == 0)
    return jnp.where(zero, 0.0, jnp.arctan2(jnp.where(zero, 0.0, y), jnp.where(zero, 1.0, x)))


def heron_product(p: ArrayLike, delta: ArrayLike, q: ArrayLike) -> Array:
    """16 x (area of the triangle with sides p, delta, q)^2 in Kahan's
    ordering: positive exactly when two circles of radii p and q whose centres
    are delta apart cross (see ``_heron``)."""
    return _heron(jnp.asarray(p), jnp.asarray(delta), jnp.asarray(q))[0]


def _heron(p: Array, delta: Array, q: Array) -> tuple[Array, Array]:
    """16 x (area of the triangle with sides p, delta, q)^2, Kahan's ordering.

    Sorting the sides (a >= b >= c) and grouping as
    (a + (b + c)) (c - (a - b)) (c + (a - b)) (a + (b - c)) makes the product
    symmetric in its arguments and accurate to a few ulps, so circle A crossing
    circle B is decided exactly as B crossing A. Also returns whether q is the
    largest side (used for nesting when the product is not positive).
    """
    a = jnp.maximum(jnp.maximum(p, delta), q)
    c = jnp.minimum(jnp.minimum(p, delta), q)
    b = jnp.maximum(jnp.minimum(p, delta), jnp.minimum(jnp.maximum(p, delta), q))  # median, exact
    prod = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c))
    return prod, q >= a


def crossing_half_width(p: ArrayLike, delta: ArrayLike, q: ArrayLike) -> tuple[Array, Array, Array]:
    """Half-width, seen from the centre of circle p, of its arc inside circle q
    (centres delta apart): ``(half, crosses, inside)``. ``crosses`` is False
    for disjoint, nested, tangent or concentric circles; then ``half`` is 0 and
    ``inside`` says whether circle p lies in the closed disk q.

    half = atan2(sqrt(Heron), p^2 + delta^2 - q^2): full precision near
    tangency, where arccos of the law of cosines loses half the digits, and
    for radii far from 1 (no term is formed as a difference of squares of
    large numbers: (p - q)(p + q) + delta^2)."""
    p, delta, q = jnp.asarray(p), jnp.asarray(delta), jnp.asarray(q)
    prod, q_largest = _heron(p, delta, q)
    crosses = (prod > 0) & (delta > 0)
    # p^2 + delta^2 - q^2 with q^2 taken from the nearer of p^2 and delta^2
    # exactly (Sterbenz): nearly identical circles (p ~ q) and the limb seen
    # from the star under a huge disk (delta ~ q >> p) keep full precision.
    cos_term = jnp.where(delta >= p, (delta - q) * (delta + q) + p * p, (p - q) * (p + q) + delta * delta)
    half = jnp.where(
        crosses,
        jnp.arctan2(safe_sqrt(jnp.where(crosses, prod, 0.0)), jnp.where(crosses, cos_term, 1.0)),
        0.0,
    )
    return half, crosses, ~crosses & q_largest


def wrap_angle(a: ArrayLike) -> Array:
    """a in (-3 pi, 3 pi) wrapped to (-pi, pi]."""
    a = jnp.asarray(a)
    return jnp.where(a > np.pi, a - 2.0 * np.pi, jnp.where(a <= -np.pi, a + 2.0 * np.pi, a))


def circle_intersection_angles(
    cx: ArrayLike, cy: ArrayLike, p: ArrayLike, ox: ArrayLike, oy: ArrayLike, q: ArrayLike
) -> tuple[Array, Array, Array, Array]:
    """Where circle (cx, cy, p) meets circle (ox, oy, q), seen from (cx, cy).

    Returns ``(base, half_width, crosses, inside)``: the crossing points are at
    angles ``base -/+ half_width`` about (cx, cy) (base points at (ox, oy));
    ``crosses`` is False when the circles do not cross (disjoint, nested,
    tangent or concentric), and then ``half_width`` is 0 and ``inside`` says
    whether the first circle lies in the closed second disk.

    The half-width is atan2(sqrt(Heron), p^2 + delta^2 - q^2): full precision
    near tangency, where arccos of the law of cosines loses half the digits.
    """
    dx = jnp.asarray(ox) - cx
    dy = jnp.asarray(oy) - cy
    delta = safe_hypot(dx, dy)
    base = safe_atan2(dy, dx)
    half, crosses, inside = crossing_half_width(p, delta, q)
    return base, half, crosses, inside


_COS = tuple((-1) ** k / factorial(2 * k) for k in range(14))
_SIN = tuple((-1) ** k / factorial(2 * k + 1) for k in range(14))


@jax.custom_jvp
def cos_sin(x: ArrayLike) -> tuple[Array, Array]:
    """(cos x, sin x) for |x| <= pi by their Taylor polynomials of degree 26
    and 27 in Horner form: absolute error <= 1.3e-15 (measured against numpy
    in tests/test_geometry.py), a few multiply-adds, several times cheaper
    than XLA's CPU cos and sin. The quadrature kernels need them at nodes
    along arcs of at most pi and rotate by the arc's start angle."""
    x = jnp.asarray(x)
    z = x * x
    c = jnp.full_like(x, _COS[-1])
    s = jnp.full_like(x, _SIN[-1])
    for a, b in zip(_COS[-2::-1], _SIN[-2::-1]):
        c = c * z + a
        s = s * z + b
    return c, s * x


@cos_sin.defjvp
def _cos_sin_jvp(primals, tangents):
    # d(cos, sin) = (-sin, cos) dx: no differentiation through the Horner chain
    (x,), (dx,) = primals, tangents
    c, s = cos_sin(x)
    return (c, s), (-s * dx, c * dx)
