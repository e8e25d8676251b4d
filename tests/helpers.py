"""Independent references for the tests.

``reference_deficit`` integrates in the *radial* direction,

    D = int_0^1 I(r) r Theta(r) dr ,

where Theta(r) is the total angle of the circle of radius r lying inside the
union of the disks (computed by merging angular intervals). The range is split
at every radius where Theta has a kink (|d_k +- p_k| and the radii of all
circle-circle crossing points) and each piece is integrated by adaptive
Gauss-Kronrod (scipy QUADPACK) to 1e-14. It shares no code with
``jaxppo.core.occult`` (which integrates along the boundary in angle).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy import integrate


def union_angle(rad: float, x, y, p) -> float:
    """Angle of the circle of radius ``rad`` about the origin inside the union."""
    intervals = []
    for xc, yc, pc in zip(x, y, p):
        d = np.hypot(xc, yc)
        if pc <= 0:
            continue
        if rad + d <= pc:  # circle entirely inside the disk
            return 2 * np.pi
        if d == 0 or rad <= d - pc or rad >= d + pc or rad <= pc - d:
            if rad <= pc - d:
                return 2 * np.pi
            continue
        # (d - pc)(d + pc): no cancellation for huge disks (d ~ pc >> 1)
        c = (rad * rad + (d - pc) * (d + pc)) / (2 * rad * d)
        half = np.arccos(np.clip(c, -1.0, 1.0))
        phi = np.arctan2(yc, xc)
        intervals.append((phi - half, 2 * half))
    if not intervals:
        return 0.0
    # Merge on the circle: cut at -pi.
    segs = []
    for start, width in intervals:
        a = (start + np.pi) % (2 * np.pi) - np.pi
        b = a + width
        if b > np.pi:
            segs.append((a, np.pi))
            segs.append((-np.pi, b - 2 * np.pi))
        else:
            segs.append((a, b))
    segs.sort()
    total, cur_a, cur_b = 0.0, None, None
    for a, b in segs:
        if cur_b is None or a > cur_b:
            if cur_b is not None:
                total += cur_b - cur_a
            cur_a, cur_b = a, b
        else:
            cur_b = max(cur_b, b)
    total += cur_b - cur_a
    return total


def kink_radii(x, y, p) -> list[float]:
    pts = [0.0, 1.0]
    for xc, yc, pc in zip(x, y, p):
        d = np.hypot(xc, yc)
        pts += [abs(d - pc), d + pc]
    for (x1, y1, p1), (x2, y2, p2) in itertools.combinations(zip(x, y, p), 2):
        dd = np.hypot(x2 - x1, y2 - y1)
        if dd == 0 or dd >= p1 + p2 or dd <= abs(p1 - p2):
            continue
        a = (p1 * p1 - p2 * p2 + dd * dd) / (2 * dd)
        h = np.sqrt(max(p1 * p1 - a * a, 0.0))
        mx, my = x1 + a * (x2 - x1) / dd, y1 + a * (y2 - y1) / dd
        for sgn in (1, -1):
            qx = mx + sgn * h * (y2 - y1) / dd
            qy = my - sgn * h * (x2 - x1) / dd
            pts.append(np.hypot(qx, qy))
    return sorted(v for v in set(pts) if 0.0 <= v <= 1.0)


def _smooth_map(w, upper_is_limb):
    """r-fraction and its derivative for w in [0, 1]: quadratic clustering at
    the lower end (sqrt kinks of Theta) and quadratic or quartic at the upper
    end (quartic at the limb, where I ~ (1 - r)^(1/4) for the non-linear law)."""
    if upper_is_limb:  # regularised incomplete beta I_w(2, 4)
        return 1 - (1 - w) ** 5 - 5 * w * (1 - w) ** 4, 20 * w * (1 - w) ** 3
    return 3 * w * w - 2 * w**3, 6 * w * (1 - w)


def _mu_breaks(breaks_mu):
    if breaks_mu is None:
        return []
    return [float(np.sqrt(max(1.0 - m * m, 0.0))) for m in breaks_mu]


def reference_deficit(intensity_r, x, y, p, epsabs=1e-15, breaks_mu=None) -> float:
    """int I dA over (union of disks) cap (unit disk); intensity_r(r) -> I.
    ``breaks_mu``: kinks of a tabulated profile (table nodes), split there."""
    x, y, p = (np.atleast_1d(np.asarray(v, float)) for v in (x, y, p))
    pts = sorted(set(kink_radii(x, y, p) + [b for b in _mu_breaks(breaks_mu) if 0 < b < 1]))
    total = 0.0
    for a, b in zip(pts[:-1], pts[1:]):
        if b - a <= 0:
            continue
        limb = b == 1.0

        def integrand(w, a=a, b=b, limb=limb):
            f, df = _smooth_map(w, limb)
            rr = a + (b - a) * f
            return intensity_r(rr) * rr * union_angle(rr, x, y, p) * (b - a) * df

        val, _ = integrate.quad(integrand, 0.0, 1.0, epsabs=epsabs, epsrel=1e-14, limit=400)
        total += val
    return total


def reference_total(intensity_r, breaks_mu=None) -> float:
    pts = sorted(set([0.0, 1.0] + [b for b in _mu_breaks(breaks_mu) if 0 < b < 1]))
    total = 0.0
    for a, b in zip(pts[:-1], pts[1:]):
        limb = b == 1.0

        def integrand(w, a=a, b=b, limb=limb):
            f, df = _smooth_map(w, limb)
            rr = a + (b - a) * f
            return intensity_r(rr) * rr * (b - a) * df

        total += integrate.quad(integrand, 0, 1, epsabs=1e-15, epsrel=1e-14, limit=400)[0]
    return 2 * np.pi * total


def union_area(x, y, p) -> float:
    """Area of (union of disks) cap (unit disk) for a uniform star, by the same
    radial route (closed forms for Theta)."""
    return reference_deficit(lambda r: 1.0, x, y, p)


# ---------------------------------------------------------------------------
# Configurations for the accuracy tests.
# ---------------------------------------------------------------------------
KEPLER20_P100 = (1.0984732924, -1.74332475724, 2.46865245453, -0.995093958392)


def adversarial_single():
    """(x, y, p) single disks at the points where methods fail."""
    out = []
    for p in (1e-4, 1e-2, 0.1, 0.5):
        for b in (0.0, p, 1 - p, 1.0, 1 + p):
            for eps in (0.0, 1e-12, -1e-12):
                bb = b + eps
                if bb < 0:
                    continue
                out.append(([bb * np.cos(0.3)], [bb * np.sin(0.3)], [p]))
    return out


def adversarial_pairs():
    """Pairs and triples: tangent, nested, concentric, identical, on the limb."""
    cfgs = []
    c = (0.31, 0.12)
    for p1, p2 in ((0.05, 0.03), (0.1, 0.1), (0.2, 0.02), (1e-4, 0.03)):
        for dist in (p1 + p2, abs(p1 - p2), 0.0, 0.5 * (p1 + p2)):
            for eps in (0.0, 1e-12, -1e-12):
                dd = dist + eps
                if dd < 0:
                    continue
                cfgs.append(([c[0], c[0] + dd * 0.6], [c[1], c[1] + dd * 0.8], [p1, p2]))
    # identical and nested
    cfgs.append(([0.4, 0.4], [0.2, 0.2], [0.05, 0.05]))
    cfgs.append(([0.4, 0.41], [0.2, 0.2], [0.05, 0.02]))
    # straddling the limb together (and one inside the other on the limb)
    cfgs.append(([0.97, 0.99], [0.1, 0.05], [0.05, 0.04]))
    cfgs.append(([0.0, 0.02], [1.0, 1.0], [0.1, 0.05]))
    cfgs.append(([0.6, 0.62], [0.8, 0.79], [0.3, 0.1]))
    # tangent to each other on the limb, and internally tangent to the limb
    cfgs.append(([0.9, 0.9], [0.0, 0.15], [0.1, 0.05]))
    # entirely off the star; one on, one off
    cfgs.append(([1.5, 1.6], [0.0, 0.0], [0.1, 0.1]))
    cfgs.append(([0.2, 1.6], [0.0, 0.0], [0.1, 0.1]))
    # a big disk covering the whole star plus a small one
    cfgs.append(([0.1, 0.3], [0.0, 0.1], [1.5, 0.05]))
    # three overlapping disks, and three in a chain over the limb
    cfgs.append(([0.3, 0.33, 0.31], [0.1, 0.12, 0.08], [0.03, 0.02, 0.025]))
    cfgs.append(([0.95, 1.0, 1.05], [0.1, 0.12, 0.1], [0.06, 0.05, 0.06]))
    return cfgs


def random_configs(rng, n, k, pmin=1e-3, pmax=0.3):
    out = []
    for _ in range(n):
        p = np.exp(rng.uniform(np.log(pmin), np.log(pmax), k))
        cx, cy = rng.uniform(-1.1, 1.1, 2)
        x = cx + rng.normal(0, 1, k) * p.max()
        y = cy + rng.normal(0, 1, k) * p.max()
        out.append((list(x), list(y), list(p)))
    return out


# ---------------------------------------------------------------------------
# Adversarial classes for tests/core/test_adversarial.py and
# benchmarks/adversarial_table.py (issue 16): seeded generators of scenes of
# up to three disks, each list entry (x, y, r).
# ---------------------------------------------------------------------------
def _through(px, py, radii, angles):
    """Circles of the given radii through the point (px, py), their centres
    in the given directions from it."""
    radii, angles = np.asarray(radii, float), np.asarray(angles, float)
    return list(px + radii * np.cos(angles)), list(py + radii * np.sin(angles)), list(radii)


def adversarial_classes(rng, n=8):
    """Scenes by class, ``n`` (or about n) of each, seeded by ``rng``."""
    out = {}
    u = lambda a, b, size=None: rng.uniform(a, b, size)  # noqa: E731
    out["random (1-3 disks)"] = [c for k in (1, 2, 3) for c in random_configs(rng, n, k)]
    for name, eps in (("tangent (exact)", 0.0), ("tangent +-1e-15", 1e-15)):
        cfgs = []
        for _ in range(n):
            p1, p2 = np.exp(u(np.log(1e-3), np.log(0.4), 2))
            cx, cy, ang = u(-0.8, 0.8), u(-0.8, 0.8), u(0, 2 * np.pi)
            sgn = rng.choice([-1.0, 1.0])
            for dist in (p1 + p2, abs(p1 - p2)):
                dd = dist * (1 + sgn * eps) if eps else dist
                cfgs.append(([cx, cx + dd * np.cos(ang)], [cy, cy + dd * np.sin(ang)], [p1, p2]))
            # tangent to the limb from inside and from outside
            for b in (1 - p1, 1 + p1):
                bb = b * (1 + sgn * eps) if eps else b
                cfgs.append(([bb * np.cos(ang)], [bb * np.sin(ang)], [p1]))
        out[name] = cfgs
    cfgs = []
    for _ in range(n):
        px, py = u(-0.9, 0.9), u(-0.4, 0.4)
        radii = np.exp(u(np.log(0.02), np.log(0.3), 3))
        angles = np.sort(u(0, 2 * np.pi, 3))
        cfgs.append(_through(px, py, radii, angles))
    out["three circles through a point"] = cfgs
    cfgs = []
    for _ in range(n):
        phi = u(0, 2 * np.pi)
        radii = np.exp(u(np.log(0.02), np.log(0.3), 2))
        cfgs.append(_through(np.cos(phi), np.sin(phi), radii, phi + u(0, 2 * np.pi, 2)))
        # and a third circle through the same limb point
        x, y, r = _through(np.cos(phi), np.sin(phi), np.append(radii, 0.1), phi + u(0, 2 * np.pi, 3))
        cfgs.append((x, y, r))
    out["crossings on the limb"] = cfgs
    cfgs = []
    for _ in range(n):
        cx, cy = u(-0.9, 0.9), u(-0.5, 0.5)
        radii = np.exp(u(np.log(0.01), np.log(0.5), 2))
        cfgs.append(([cx, cx], [cy, cy], list(radii)))
        cfgs.append(([0.0, 0.0], [0.0, 0.0], list(radii)))  # concentric with the star
        cfgs.append(([0.0, cx], [0.0, cy], [radii[0], radii[1]]))  # one on the centre, one crossing
    out["concentric"] = cfgs
    cfgs = []
    for _ in range(n):
        cx, cy, p = u(-1.1, 1.1), u(-0.5, 0.5), np.exp(u(np.log(0.01), np.log(0.5)))
        cfgs.append(([cx, cx], [cy, cy], [p, p]))
        cfgs.append(([cx, cx, cx + p], [cy, cy, cy], [p, p, 0.5 * p]))
    out["identical disks"] = cfgs
    cfgs = [([0.0], [0.0], [1.0]), ([0.0, 0.0], [0.0, 0.0], [1.0, 1.0]), ([0.0, 1.0], [0.0, 0.0], [1.0, 0.3])]
    for _ in range(n):
        phi, p = u(0, 2 * np.pi), np.exp(u(np.log(0.01), np.log(0.5)))
        cfgs.append(([0.0, np.cos(phi)], [0.0, np.sin(phi)], [1.0, p]))
        R = u(1.0, 3.0)
        off = u(0.0, R - 1.0)
        cfgs.append(([off * np.cos(phi), 0.3], [off * np.sin(phi), 0.1], [R, p]))  # covers the star
    out["disks matching / covering the star"] = cfgs
    cfgs = []
    for _ in range(n):
        p = np.exp(u(np.log(1e-6), np.log(1e-3), 2))
        cx, cy = u(-1.0, 1.0), u(-0.3, 0.3)
        cfgs.append(([cx, cx + u(-1, 1) * p.sum()], [cy, cy + u(-1, 1) * p.sum()], list(p)))
        b = 1 + u(-1, 1) * p[0]
        cfgs.append(([b], [0.0], [p[0]]))  # tiny disk on the limb
    out["tiny radii (1e-6 to 1e-3)"] = cfgs
    cfgs = []
    for _ in range(n):
        R, phi, c = 10 ** u(1, 6), u(0, 2 * np.pi), u(-0.9, 0.9)
        x, y = (R + c) * np.cos(phi), (R + c) * np.sin(phi)
        cfgs.append(([x], [y], [R]))
        q = np.exp(u(np.log(0.01), np.log(0.2)))
        cfgs.append(([x, (c + u(-1, 1) * q) * np.cos(phi)], [y, (c + u(-1, 1) * q) * np.sin(phi) + u(-0.5, 0.5)], [R, q]))
    out["huge radii (10 to 1e6)"] = cfgs
    cfgs = []
    for _ in range(n):
        dist, phi = 10 ** u(1, 8), u(0, 2 * np.pi)
        p = np.exp(u(np.log(0.01), np.log(0.3)))
        cfgs.append(([dist * np.cos(phi), u(-0.8, 0.8)], [dist * np.sin(phi), u(-0.5, 0.5)], [p, p]))
    out["far disks (10 to 1e8)"] = cfgs
    return out


def numpy_intensity(star):
    """I(mu) of a jaxppo Star written with numpy from its coefficients
    (shares no code with the engine's profile kernels; tables use their
    fitted sqrt(mu) polynomial, which is their definition)."""
    p = np.asarray(star.params, float)
    if star.law == "uniform":
        return lambda mu: np.ones_like(np.asarray(mu, float))
    if star.law == "quadratic":
        return lambda mu: 1 - p[0] * (1 - mu) - p[1] * (1 - mu) ** 2
    if star.law == "nonlinear":
        return lambda mu: 1 - sum(c * (1 - np.asarray(mu, float) ** ((k + 1) / 2)) for k, c in enumerate(p))
    if star.law == "power2":
        return lambda mu: 1 - p[0] * (1 - np.asarray(mu, float) ** p[1])
    if star.law == "tabulated" and star.interpolation == "sqrt-poly":
        from numpy.polynomial import chebyshev as C

        coef = np.asarray(star.fit_matrix, float) @ p
        return lambda mu: C.chebval(2 * np.sqrt(np.asarray(mu, float)) - 1, coef)
    raise ValueError(f"no numpy profile for {star!r}")


def pad_scenes(cfgs, k=3):
    """[scene, k] arrays; missing disks have radius 0 (absent)."""
    x = np.array([list(c[0]) + [0.0] * (k - len(c[0])) for c in cfgs])
    y = np.array([list(c[1]) + [0.0] * (k - len(c[1])) for c in cfgs])
    r = np.array([list(c[2]) + [0.0] * (k - len(c[2])) for c in cfgs])
    return x, y, r


def one_device_env(**extra) -> dict:
    """This process's environment for a subprocess of one CPU device: its
    XLA_FLAGS without a forced device count, so that the subprocess
    compiles with the same flags (such as .ci/run's optimisation level,
    which changes rounding) and its numbers equal this process's."""
    import os

    flags = [f for f in os.environ.get("XLA_FLAGS", "").split() if not f.startswith("--xla_force_host_platform_device_count")]
    env = dict(os.environ, JAX_PLATFORMS="cpu", **extra)
    env["XLA_FLAGS"] = " ".join(flags)
    return env
