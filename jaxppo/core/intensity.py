"""Radial intensity profiles I(mu) and their exact radial primitives.

Every profile is written in one of two forms:

* a *power basis* ``I(mu) = sum_k a_k mu**e_k`` (quadratic, non-linear Claret
  2000, power-2 and uniform laws are all of this form), or
* a *table* ``(mu_j, I_j)`` interpolated piecewise linearly in mu (the scheme of
  Mueller et al. 2021, Sect. 2.5), or by a natural cubic spline in mu.

For the occultation integrals (``jaxppo.core.occult``) the quantity needed is the
radial primitive

    Phi(r) = int_0^r s I(s) ds = int_mu^1 m I(m) dm ,     mu = sqrt(1 - r^2)

in the combination ``g(s) = Phi(r) / r^2`` with ``s = r^2``: by Green's theorem
the flux inside a region is the contour integral of ``g(r^2) (x dy - y dx)``.
``g`` is smooth at the stellar centre (g(0) = I(mu=1) / 2) and is evaluated here
without cancellation for s -> 0 (expm1/log1p), so contours passing through the
centre keep full precision.

All functions take plain arrays and broadcast; nothing here knows about stars,
planets or orbits.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

__all__ = [
    "halfint_coefficients",
    "halfint_g",
    "power_basis_intensity",
    "power_basis_g",
    "power_basis_total",
    "table_intensity",
    "table_g",
    "table_total",
    "table_cumulative",
    "spline_coefficients",
    "sqrt_cheb_operators",
    "cheb_g",
    "cheb_eval",
]


def _one_minus_pow(s: Array, q: Array) -> Array:
    """(1 - (1 - s)**q) for s in [0, 1], accurate for s -> 0 and safe at s = 1."""
    inside = s < 1.0
    # double-where: log1p(-1) = -inf would poison gradients through q.
    log_m2 = jnp.log1p(-jnp.where(inside, s, 0.5))
    return jnp.where(inside, -jnp.expm1(q * log_m2), 1.0)


def _ratio_one_minus_pow(s: Array, q: Array) -> Array:
    """h(s, q) = (1 - (1 - s)**q) / s, with the limit h(0, q) = q.

    Below s = eps of the dtype the two-term series q - q (q - 1) s / 2 is
    exact to rounding (and has the right slope), while the quotient would
    divide rounded subnormals (or 0 by 0): the threshold follows the dtype,
    never a float64 constant that underflows to 0 in float32."""
    small = s < jnp.finfo(jnp.result_type(s)).eps
    s_safe = jnp.where(small, 1.0, s)
    return jnp.where(small, q - 0.5 * q * (q - 1.0) * s, _one_minus_pow(s_safe, q) / s_safe)


def power_basis_intensity(
    mu: ArrayLike, a: Float[Array, " k"], e: Float[Array, " k"]
) -> Array:
    """I(mu) = sum_k a_k mu**e_k."""
    mu = jnp.asarray(mu)[..., None]
    pos = mu > 0
    mu_safe = jnp.where(pos, mu, 1.0)
    terms = jnp.where(pos, a * jnp.exp(e * jnp.log(mu_safe)), jnp.where(e == 0, a, 0.0))
    return jnp.sum(terms, axis=-1)


def power_basis_g(s: ArrayLike, a: Float[Array, " k"], e: Float[Array, " k"]) -> Array:
    """g(s) = Phi(r) / r**2 at s = r**2 in [0, 1] for I = sum_k a_k mu**e_k.

    Phi(r) = sum_k a_k (1 - mu**(e_k + 2)) / (e_k + 2) and mu**2 = 1 - s, so
    g(s) = sum_k a_k / (e_k + 2) * h(s, (e_k + 2) / 2). Works for any real
    exponents (two transcendental calls per term); values of s above 1 are
    clipped to the limb (callers mask them out).
    """
    s = jnp.asarray(s)
    s = jnp.where(s < 1.0, s, 1.0)[..., None]
    q = 0.5 * (e + 2.0)
    return jnp.sum(a / (e + 2.0) * _ratio_one_minus_pow(s, q), axis=-1)


def power_basis_total(a: Float[Array, " k"], e: Float[Array, " k"]) -> Array:
    """Total flux F0 = 2 pi int_0^1 I(mu) mu dmu = 2 pi Phi(1)."""
    return 2.0 * jnp.pi * jnp.sum(a / (e + 2.0))


# --------------------------------------------------------------------------
# Half-integer exponents (uniform, linear, quadratic, Claret non-linear):
# a rational function of v = mu**(1/2) with no cancellation anywhere.
# --------------------------------------------------------------------------
def halfint_coefficients(a: Float[Array, " k"], twice_e: tuple[int, ...]) -> Array:
    """Coefficients q_i (ascending powers of v) of Q(v) with g = Q(v) / (1+v+v^2+v^3).

    With v = mu**(1/2) and n_k = 2 e_k + 4,
    (1 - mu**(e_k + 2)) / r**2 = (1 - v**n_k) / (1 - v**4)
                               = (1 + v + ... + v**(n_k - 1)) / (1 + v + v**2 + v**3),
    so g(s) = sum_k a_k / (e_k + 2) (1 + ... + v**(n_k - 1)) / (1 + v + v**2 + v**3).
    ``twice_e`` are the static integers 2 e_k.
    """
    n = [te + 4 for te in twice_e]
    width = max(n)
    mask = np.array([[1.0 if i < nk else 0.0 for i in range(width)] for nk in n])
    scale = jnp.asarray([2.0 / (te + 4.0) for te in twice_e], dtype=a.dtype)
    return jnp.sum((a * scale)[:, None] * jnp.asarray(mask, dtype=a.dtype), axis=0)


def _quarter_root(s: ArrayLike) -> Array:
    """v = (1 - s)**(1/4), 0 for s >= 1."""
    m2 = 1.0 - jnp.asarray(s)
    inside = m2 > 0
    # double-where: d sqrt / ds is infinite on the limb and beyond it.
    return jnp.where(inside, jnp.sqrt(jnp.sqrt(jnp.where(inside, m2, 1.0))), 0.0)


def halfint_poly(s: ArrayLike, coef) -> Array:
    """Q(v) = sum_k coef[k] v^k (Horner), v = (1 - s)**(1/4), s clipped to [0, 1]."""
    v = _quarter_root(s)
    out = jnp.zeros_like(v) + coef[-1]
    for c in coef[-2::-1]:
        out = out * v + c
    return out


def halfint_g(s: ArrayLike, coef: Float[Array, " n"]) -> Array:
    """g(s) = Q(v) / (1 + v + v^2 + v^3), v = (1 - s)**(1/4), s clipped to [0, 1]."""
    v = _quarter_root(s)
    return halfint_poly(s, coef) / (((v + 1.0) * v + 1.0) * v + 1.0)


# --------------------------------------------------------------------------
# Smooth tables in a Chebyshev basis of v = mu**(1/2): well conditioned in
# float32 as in float64.
# --------------------------------------------------------------------------
def sqrt_cheb_operators(mu: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Linear maps (float64, numpy) from table values to Chebyshev
    coefficients (in x = 2 v - 1, v = mu**(1/2)) of

    * the least-squares fit I(v) of degree ``degree`` (``fit``), and
    * Q(v) = (H(1) - H(v)) / (1 - v), H(v) = 2 int_0^v t^3 I(t) dt
      (``q``), so that g = Q(v) / (1 + v + v^2 + v^3).

    The fit is solved in the Chebyshev basis (no Vandermonde in v), and the
    product, integral and exact division act on Chebyshev series.
    """
    from numpy.polynomial import chebyshev as C

    x = 2.0 * np.sqrt(mu) - 1.0
    design = C.chebvander(x, degree)
    fit = np.linalg.pinv(design)  # [degree + 1, n]
    t3 = C.poly2cheb([1 / 8, 3 / 8, 3 / 8, 1 / 8])  # v^3 = ((x + 1) / 2)^3
    cols = []
    for j in range(degree + 1):
        e = np.zeros(degree + 1)
        e[j] = 1.0
        h = C.chebint(C.chebmul(e, t3), lbnd=-1.0) * 2.0 * 0.5  # 2 int t^3 I dt, dt = dx / 2
        num = C.chebsub([C.chebval(1.0, h)], h)  # H(1) - H(x), zero at x = 1
        quo, rem = C.chebdiv(num, [0.5, -0.5])  # divide by 1 - v = (1 - x) / 2
        cols.append(np.pad(quo, (0, degree + 4 - quo.size)))
    q = np.stack(cols, axis=1) @ fit  # [degree + 4, n]
    return fit, q


def cheb_g(s: ArrayLike, qcheb: Float[Array, " n"]) -> Array:
    """g(s) = Q(v) / (1 + v + v^2 + v^3) with Q given by Chebyshev
    coefficients in x = 2 v - 1 (Clenshaw), v = (1 - s)**(1/4)."""
    m2 = 1.0 - jnp.asarray(s)
    inside = m2 > 0
    v = jnp.where(inside, jnp.sqrt(jnp.sqrt(jnp.where(inside, m2, 1.0))), 0.0)
    return cheb_eval(2.0 * v - 1.0, qcheb) / (((v + 1.0) * v + 1.0) * v + 1.0)


def cheb_eval(x: Array, coef: Float[Array, " n"]) -> Array:
    """Chebyshev series sum_j coef_j T_j(x) by Clenshaw's recurrence."""
    b1 = jnp.zeros_like(x)
    b2 = jnp.zeros_like(x)
    for c in coef[:0:-1]:
        b1, b2 = 2.0 * x * b1 - b2 + c, b1
    return x * b1 - b2 + coef[0]


# --------------------------------------------------------------------------
# Tables: piecewise cubic in mu (natural cubic spline, or linear as a special
# case), I(m) = sum_i b[j, i] m**i on the segment [mu_j, mu_j+1].
# --------------------------------------------------------------------------
def spline_coefficients(mu: Float[Array, " n"], inten: Float[Array, " n"], kind: str) -> Array:
    """Monomial coefficients b[j, i] (i = 0..3) of the interpolant on each segment.

    ``kind``: "linear" (the scheme of Mueller et al. 2021) or "cubic" (natural
    cubic spline, C2). Linear in ``inten`` so gradients flow to the table.
    """
    h = mu[1:] - mu[:-1]
    slope = (inten[1:] - inten[:-1]) / h
    n = mu.shape[0]
    if kind == "linear":
        c1 = slope
        c2 = jnp.zeros_like(h)
        c3 = jnp.zeros_like(h)
    elif kind == "cubic":
        # Second derivatives M_j with M_0 = M_{n-1} = 0 (natural spline).
        if n < 3:
            raise ValueError(f"a cubic spline needs at least 3 mu points, got {n}")
        diag = 2.0 * (h[:-1] + h[1:])
        rhs = 6.0 * (slope[1:] - slope[:-1])
        lower = jnp.concatenate([jnp.zeros(1, h.dtype), h[1:-1]])
        upper = jnp.concatenate([h[1:-1], jnp.zeros(1, h.dtype)])
        import jax

        m_inner = jax.lax.linalg.tridiagonal_solve(lower, diag, upper, rhs[:, None])[:, 0]
        m2 = jnp.concatenate([jnp.zeros(1, h.dtype), m_inner, jnp.zeros(1, h.dtype)])
        c1 = slope - h * (2.0 * m2[:-1] + m2[1:]) / 6.0
        c2 = m2[:-1] / 2.0
        c3 = (m2[1:] - m2[:-1]) / (6.0 * h)
    else:
        raise ValueError(f"interpolation must be 'linear' or 'cubic', got {kind!r}")
    # Local (m - mu_j)^i -> global m^i.
    c0 = inten[:-1]
    a = mu[:-1]
    b0 = c0 - c1 * a + c2 * a**2 - c3 * a**3
    b1 = c1 - 2.0 * c2 * a + 3.0 * c3 * a**2
    b2 = c2 - 3.0 * c3 * a
    b3 = c3
    return jnp.stack([b0, b1, b2, b3], axis=-1)


def _segment_phi(b: Array, lo: Array, hi: Array) -> Array:
    """int_lo^hi m I(m) dm on one segment with I = sum_i b_i m^i."""
    return sum(b[..., i] * (hi ** (i + 2) - lo ** (i + 2)) / (i + 2) for i in range(4))


def table_cumulative(mu: Float[Array, " n"], b: Float[Array, "n-1 4"]) -> Array:
    """Phi at the nodes, Phi_j = int_{mu_j}^1 m I(m) dm (mu ascending, mu[-1] = 1)."""
    seg = _segment_phi(b, mu[:-1], mu[1:])
    tail = jnp.cumsum(seg[::-1])[::-1]
    return jnp.concatenate([tail, jnp.zeros(1, dtype=tail.dtype)])


def _segment(mu_nodes: Array, m: Array) -> Array:
    n = mu_nodes.shape[0]
    return jnp.clip(jnp.searchsorted(mu_nodes, m, side="right") - 1, 0, n - 2)


def table_intensity(mu: ArrayLike, mu_nodes: Float[Array, " n"], b: Float[Array, "n-1 4"]) -> Array:
    """Evaluate the piecewise-cubic interpolant at ``mu`` (clipped to [0, 1])."""
    m = jnp.clip(jnp.asarray(mu), 0.0, 1.0)
    bj = b[_segment(mu_nodes, m)]
    return ((bj[..., 3] * m + bj[..., 2]) * m + bj[..., 1]) * m + bj[..., 0]


def table_g(
    s: ArrayLike, mu_nodes: Float[Array, " n"], b: Float[Array, "n-1 4"], phi_nodes: Float[Array, " n"]
) -> Array:
    """g(s) = Phi(r) / r**2 for the piecewise-cubic table.

    On the segment [m_j, m_j+1] (with s_1 = 1 - m_j+1^2),
    Phi(m) = Phi_{j+1} + sum_i b_i (m_j+1^(i+2) - m^(i+2)) / (i + 2), and
    m_j+1^n - m^n = (s - s_1) / (m_j+1 + m) * sum_l m_j+1^l m^(n-1-l)
    has no cancellation, so g keeps full precision down to s = 0 (where the top
    segment has Phi_{j+1} = 0 and s_1 = 0).
    """
    s = jnp.asarray(s)
    s = jnp.where(s < 1.0, s, 1.0)
    m2 = 1.0 - s
    m = jnp.where(m2 > 0, jnp.sqrt(jnp.where(m2 > 0, m2, 1.0)), 0.0)
    j = _segment(mu_nodes, m)
    m1 = mu_nodes[j + 1]
    bj = b[j]
    s1 = 1.0 - m1 * m1
    bracket = 0.0
    for i in range(4):
        n = i + 2
        geo = sum(m1**l * m ** (n - 1 - l) for l in range(n))
        bracket = bracket + bj[..., i] * geo / n
    bracket = bracket / (m1 + m)
    top = s1 == 0.0
    # On the top segment (s1 = 0) both quotients are replaced; elsewhere
    # s >= s1 > 0. The double where keeps 0/0 out of the gradient.
    s_safe = jnp.where(top | (s <= 0), 1.0, s)
    g = jnp.where(top, 0.0, phi_nodes[j + 1] / s_safe) + jnp.where(top, 1.0, (s - s1) / s_safe) * bracket
    return g


def table_total(mu_nodes: Float[Array, " n"], b: Float[Array, "n-1 4"]) -> Array:
    """F0 = 2 pi Phi(r = 1) for the table."""
    return 2.0 * jnp.pi * table_cumulative(mu_nodes, b)[0]
