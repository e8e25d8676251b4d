"""Static quadrature rules (numpy, built once per order and cached)."""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["gauss_legendre_01", "clustered_rule"]


@functools.lru_cache(maxsize=None)
def gauss_legendre_01(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(order)
    return 0.5 * (x + 1.0), 0.5 * w


def _beta_map(u: np.ndarray, k0: int, k1: int) -> tuple[np.ndarray, np.ndarray]:
    """Regularised incomplete beta I_u(k0, k1) and its derivative (integer k).

    Near u = 0 it behaves like u**k0 and near u = 1 like 1 - (1 - u)**k1, so a
    rule mapped through it clusters nodes at the ends where k > 1.
    """
    from math import comb

    n = k0 + k1 - 1
    w = sum(comb(n, j) * u**j * (1 - u) ** (n - j) for j in range(k0, n + 1))
    c = 1.0 / sum(comb(k1 - 1, j) * (-1) ** j / (k0 + j) for j in range(k1))
    dw = c * u ** (k0 - 1) * (1 - u) ** (k1 - 1)
    return w, dw


@functools.lru_cache(maxsize=None)
def clustered_rule(order: int, power: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre on [0, 1] mapped through I_u(power, power), so nodes
    cluster like u**power at both ends.

    A planet's circle crossing the stellar limb makes the integrand behave like
    (t - t_e)**(q / 2) at the crossing (intensity ~ mu**q, mu**2 linear in t);
    the power-4 map turns that into u**(2 q), smooth enough for spectral
    convergence for every law we support (q = 1/2 steps and power-2 alpha).
    """
    u, w = gauss_legendre_01(order)
    t, dt = _beta_map(u, power, power)
    return t, w * dt
