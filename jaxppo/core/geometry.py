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
           "circle_intersection_angles", "wrap_angle", "cos_sin",
           "kepler_eccentric_anomaly", "conjunction_mean_anomaly", "orbit_position"]


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
    in tests/core/test_geometry.py), a few multiply-adds, several times cheaper
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


# Markley's (1995, Celest. Mech. 63, 101) Pade starter, then fixed Halley
# steps: against a 60-digit reference (tests/core/test_geometry.py) the starter
# plus 2 steps is within 2 ulp x the equation's condition number
# 1 / (1 - e cos E) for every e up to 0.9999 and |M| from 1e-16 to pi
# (Danby's starter M + 0.85 e needed > 6 steps at e = 0.999, M -> 0). One
# spare step; a fixed count keeps the kernel branch-free under vmap, and
# steps after convergence change nothing (the residual is zero to rounding).
_KEPLER_STEPS = 3


def _kepler_halley(M, e, xp):
    """E with E - e sin E = M for M already in [-pi, pi] (numpy or jax)."""
    am = xp.abs(M)
    alpha = (3.0 * np.pi**2 + 1.6 * np.pi * (np.pi - am) / (1.0 + e)) / (np.pi**2 - 6.0)
    d = 3.0 * (1.0 - e) + alpha * e
    q = 2.0 * alpha * d * (1.0 - e) - am * am
    r = 3.0 * alpha * d * (d - 1.0 + e) * am + am * am * am
    w = xp.cbrt(xp.abs(r) + xp.sqrt(q * q * q + r * r)) ** 2  # q^3 + r^2 > 0 for e <= 1
    E = xp.sign(M) * (2.0 * r * w / (w * w + w * q + q * q) + am) / d
    for _ in range(_KEPLER_STEPS):
        sE, cE = xp.sin(E), xp.cos(E)
        f = E - e * sE - M
        f1 = 1.0 - e * cE
        E = E - f / (f1 - 0.5 * f * e * sE / f1)
    return E


def _reduce_anomaly(M, xp):
    """M wrapped to [-pi, pi] (the solver's domain; E keeps the same
    multiples of 2 pi, which sin and cos of E ignore)."""
    return M - 2.0 * np.pi * xp.round(M / (2.0 * np.pi))


@jax.custom_jvp
def kepler_eccentric_anomaly(M: ArrayLike, e: ArrayLike) -> Array:
    """Eccentric anomaly E [rad] in [-pi, pi] solving Kepler's equation
    E - e sin E = M (mean anomaly M [rad], any value; eccentricity
    0 <= e < 1). Within 2 ulp x 1 / (1 - e cos E) (the rounding of M
    amplified by the equation's conditioning) for e up to 0.9999. The derivatives
    come from the implicit function theorem, dE = (dM + sin E de) /
    (1 - e cos E), so gradients are exact and do not pass through the
    iterations; e = 0 returns M (wrapped) exactly."""
    M, e = jnp.asarray(M), jnp.asarray(e)
    return _kepler_halley(_reduce_anomaly(M, jnp), e, jnp)


@kepler_eccentric_anomaly.defjvp
def _kepler_jvp(primals, tangents):
    (M, e), (dM, de) = primals, tangents
    E = kepler_eccentric_anomaly(M, e)
    sE, cE = jnp.sin(E), jnp.cos(E)
    return E, (dM + sE * de) / (1.0 - e * cE)


def conjunction_mean_anomaly(e: ArrayLike, omega_rad: ArrayLike, xp=jnp) -> Array:
    """Mean anomaly [rad] at conjunction (mid-transit), where the true
    anomaly is f = pi/2 - omega: the time of periastron is
    t0 - P M_c / (2 pi)."""
    f = 0.5 * np.pi - omega_rad
    E = 2.0 * xp.arctan2(xp.sqrt(1.0 - e) * xp.sin(0.5 * f), xp.sqrt(1.0 + e) * xp.cos(0.5 * f))
    return E - e * xp.sin(E)


def orbit_position(t, period, t0, a, inc_rad, e, omega_rad, xp=jnp):
    """Sky position (x, y, z) [R*] of a Keplerian orbit at times t [d]
    (docs/conventions.md): t0 is the time of conjunction (mid-transit),
    omega the argument of periastron measured as in Winn (2010), batman and
    jaxoplanet (omega = pi/2: periastron at transit). With theta = f + omega
    - pi/2 (0 at conjunction) the planet is at x = r sin(theta),
    y = r cos(theta) cos(i), z = r cos(theta) sin(i); e = 0 gives the
    circular orbit with phi = theta. ``xp=numpy`` evaluates on the host."""
    t = xp.asarray(t)
    # the orbit's phase as a fraction in [-1/2, 1/2] first: the mean anomaly
    # then keeps full precision many periods away from t0
    u = (t - t0) / period
    M = 2.0 * np.pi * (u - xp.round(u)) + conjunction_mean_anomaly(e, omega_rad, xp)
    if xp is jnp:
        E = kepler_eccentric_anomaly(M, e)
    else:
        E = _kepler_halley(_reduce_anomaly(M, np), e, np)
    sE, cE = xp.sin(E), xp.cos(E)
    rc = a * (cE - e)                       # r cos f
    rs = a * xp.sqrt(1.0 - e * e) * sE      # r sin f
    # rotate by omega - pi/2: omega = 90 deg multiplies by exactly (1, 0)
    w = omega_rad - 0.5 * np.pi
    cw, sw = xp.cos(w), xp.sin(w)
    s_theta = rs * cw + rc * sw             # r sin(theta)
    c_theta = rc * cw - rs * sw             # r cos(theta)
    return s_theta, c_theta * xp.cos(inc_rad), c_theta * xp.sin(inc_rad)
