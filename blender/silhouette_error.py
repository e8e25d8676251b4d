"""How much flux the polygon outlines of Blender's UV spheres leave, against
circles (no Blender needed; numpy only):

    python blender/silhouette_error.py

A UV sphere with n segments, seen along its poles, has a regular n-gon as
outline; render_golden.py scales it so that the n-gon has the circle's area,
so its radius deviates by dr(theta) = r_poly(theta) - r, of either sign and
zero on average over each edge. The flux error of a planet is then, to first
order in dr, the line integral of dr * I(mu) along the part of its outline
that lies on the star, over the total flux; the star's own outline counts
where a planet covers the limb (with I(mu = 0)). Both are scanned over the
planet's distance from the centre and the polygons' relative rotation, for a
quadratic star (u1 = 0.4, u2 = 0.26), and the largest |error| is printed.
"""

from __future__ import annotations

import numpy as np

U1, U2 = 0.4, 0.26
F0 = np.pi * (1.0 - U1 / 3.0 - U2 / 6.0)


def intensity(r2):
    mu = np.sqrt(np.clip(1.0 - r2, 0.0, 1.0))
    return 1.0 - U1 * (1.0 - mu) - U2 * (1.0 - mu) ** 2


def dr(theta, r, n):
    """Radius of the area-matched regular n-gon (a vertex at theta = 0) minus r."""
    rc = r * np.sqrt(np.pi / (0.5 * n * np.sin(2 * np.pi / n)))
    apothem = rc * np.cos(np.pi / n)
    local = np.mod(theta, 2 * np.pi / n) - np.pi / n
    return apothem / np.cos(local) - r


def planet_outline_error(p, n, d, psi, m=40_000):
    th = np.linspace(0.0, 2 * np.pi, m, endpoint=False)
    x, y = d + p * np.cos(th), p * np.sin(th)
    on = x * x + y * y < 1.0
    w = dr(th - psi, p, n)[on] * intensity(x[on] ** 2 + y[on] ** 2)
    return float(np.sum(w) * p * (2 * np.pi / m) / F0)


def star_outline_error(p, n, d, psi, m=40_000):
    """Limb arc covered by a planet of radius p at distance d: the star's polygon
    adds or removes area there that the unocculted frame counted."""
    if d + p <= 1.0 or d - p >= 1.0:
        return 0.0
    half = np.arccos(np.clip((1.0 + d * d - p * p) / (2.0 * d), -1.0, 1.0))
    ph = np.linspace(-half, half, m)
    return float(np.sum(dr(ph - psi, 1.0, n)) * (2 * half / m) * intensity(1.0) / F0)


def main():
    print(f"{'p':>6s} {'planet segs':>11s} {'max |dF| planet':>16s}")
    for p in (0.018, 0.04, 0.07, 0.1):
        for n in (64, 128, 256):
            worst = max(abs(planet_outline_error(p, n, d, psi))
                        for d in np.linspace(0.0, 1.0 + p, 60) for psi in np.linspace(0, 2 * np.pi / n, 5))
            print(f"{p:6.3f} {n:11d} {worst:16.2e}")
    print(f"{'p':>6s} {'star segs':>11s} {'max |dF| limb':>16s}")
    for p in (0.018, 0.04, 0.07, 0.1):
        for n in (256, 512, 1024):
            worst = max(abs(star_outline_error(p, n, d, psi))
                        for d in np.linspace(1.0 - p, 1.0 + p, 61) for psi in np.linspace(0, 2 * np.pi / n, 9))
            print(f"{p:6.3f} {n:11d} {worst:16.2e}")


if __name__ == "__main__":
    main()
