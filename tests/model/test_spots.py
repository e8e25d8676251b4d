"""Rotating spotted star (Star.with_spots) against independent references:
a brute-force pixel sum in plain numpy (its own spot geometry, built from
the star's frame with explicit basis vectors), the small-spot formula of
jaxppo.activity.spot_flux, and finite differences for the gradients."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo import RasterSettings
from jaxppo.model._raster import raster_flux
from jaxppo.model._star import Spots
from jaxppo.activity import spot_flux

U1, U2 = 0.495, 0.154
STAR = jp.Star.quadratic(U1, U2)


# ---- the independent reference ------------------------------------------------


def numpy_spot_centre(lat, lon, t, period, inc, t_ref, obliquity):
    """Sky unit vector of a spot centre, built in the star's frame: z_s is the
    rotation axis, the observer sits at o = (sin i, 0, cos i) (sub-observer
    longitude 0), the spot at star longitude l = 2 pi (t - t_ref)/P - lon;
    sky axes y = (-cos i, 0, sin i) (the projected axis), x = y cross o."""
    lat, lon, inc, psi = np.deg2rad([lat, lon, inc, obliquity])
    ell = 2 * np.pi * (t - t_ref) / period - lon
    s = np.array([np.cos(lat) * np.cos(ell), np.cos(lat) * np.sin(ell), np.sin(lat)])
    o = np.array([np.sin(inc), 0.0, np.cos(inc)])
    ysky = np.array([-np.cos(inc), 0.0, np.sin(inc)])
    xsky = np.cross(ysky, o)
    x, y, z = s @ xsky, s @ ysky, s @ o
    return x * np.cos(psi) + y * np.sin(psi), -x * np.sin(psi) + y * np.cos(psi), z


def numpy_flux(spots, t, planets=(), n=2000):
    """Flux relative to the unspotted star by a plain pixel sum over an n x n
    grid on [-1, 1]^2: sum of I(mu) m(x, y) (1 - planet coverage) over
    sum of I(mu) (the grid's own unspotted total, so the limb's aliasing
    cancels). Spot profile: 1 inside radius - edge/2, smoothstep to 0 at
    radius + edge/2 (in angular distance, arccos of the dot product).
    Planet coverage is anti-aliased linearly in the distance to its edge."""
    pix = 2.0 / n
    c = -1 + (np.arange(n) + 0.5) * pix
    X, Y = np.meshgrid(c, c)
    r2 = X**2 + Y**2
    inside = r2 < 1
    X, Y = X[inside], Y[inside]
    Z = np.sqrt(1 - X**2 - Y**2)
    inten = 1 - U1 * (1 - Z) - U2 * (1 - Z) ** 2
    total = inten.sum()
    m = np.ones_like(X)
    for k in range(len(spots["lat"])):
        vx, vy, vz = numpy_spot_centre(spots["lat"][k], spots["lon"][k], t, spots["period"], spots.get("inc", 90.0),
                                       spots.get("t_ref", 0.0), spots.get("obliquity", 0.0))
        theta = np.arccos(np.clip(X * vx + Y * vy + Z * vz, -1, 1))
        edge = np.deg2rad(spots.get("edge", 0.5))
        s = np.clip((np.deg2rad(spots["radius"][k]) - theta) / edge + 0.5, 0, 1)
        m -= spots["contrast"][k] * s * s * (3 - 2 * s)
    vis = np.ones_like(X)
    for px, py, pr in planets:
        d = np.hypot(X - px, Y - py)
        vis *= 1 - np.clip((pr - d) / pix + 0.5, 0, 1)
    return float(np.sum(inten * m * vis) / total)


# ---- (a) rotational modulation -------------------------------------------------

SPOTS_A = dict(lat=[25.0, -10.0], lon=[40.0, 200.0], radius=[12.0, 8.0], contrast=[0.6, 0.4],
               period=12.0, inc=70.0, t_ref=1.0, obliquity=20.0, edge=3.0)


def _unocculted(spots_kw, t):
    star = STAR.with_spots(**spots_kw)
    far = np.full((len(t), 1), 5.0)  # a planet far off the star: the unocculted flux
    return np.asarray(raster_flux(star, far, np.zeros_like(far), np.full_like(far, 0.05), times=t))


def test_rotational_modulation_matches_numpy_pixel_sum():
    t = np.linspace(0.0, 12.0, 6)
    f = _unocculted(SPOTS_A, t)
    ref = np.array([numpy_flux(SPOTS_A, tt) for tt in t])
    depth = 1 - ref.min()
    assert depth > 0.01  # a real modulation (two large spots)
    assert np.ptp(ref) > 0.005
    # measured 3.5e-7; the 2000 x 2000 sum's own error is ~2e-7 (n = 1000 and
    # 2000 differ by 6e-7, second order), a 1 % error of the depth is 3e-4
    assert np.max(np.abs(f - ref)) < 1e-6, np.max(np.abs(f - ref))


def test_small_spot_limit_matches_dorren_term():
    """A 1-deg spot: the cap integral equals the small-spot term of
    activity.spot_flux up to its neglected O(rho^2) curvature (relative
    ~3e-4) and the smooth edge's O((edge/rho)^2) area change."""
    kw = dict(lat=[30.0], lon=[0.0], radius=[1.0], contrast=[0.59], period=10.0, inc=60.0, edge=0.05)
    t = np.linspace(0.0, 10.0, 21)
    f = _unocculted(kw, t)
    small = 1 + np.asarray(spot_flux(t, [0.0], [30.0], [1.0], 0.59, 10.0, inc=60.0, u1=U1, u2=U2))
    depth = 1 - small.min()
    assert depth > 1e-4
    assert np.max(np.abs(f - small)) < 2e-3 * depth, np.max(np.abs(f - small)) / depth
    # behind the limb (mu = cos 60 sin 30 - sin 60 cos 30 cos(phase) < 0 around
    # phase 180 deg) both give exactly the unspotted star
    hidden = small == 1.0
    assert hidden.sum() >= 3 and np.all(f[hidden] == 1.0)


def test_spot_behind_limb_leaves_star_unspotted():
    kw = dict(lat=[-60.0], lon=[180.0], radius=[5.0], contrast=[1.0], period=10.0, inc=60.0)
    # at t = 0 the spot is at the far side (mu = cos 60 sin(-60) - sin 60 cos 60 < -0.08)
    f = _unocculted(kw, np.array([0.0]))
    assert abs(f[0] - 1.0) < 1e-15


# ---- (b) a planet crossing a spot ----------------------------------------------

# Star equator-on, spot at latitude asin(0.3) on the central meridian at
# mid-transit; the planet's chord is at b = 0.3, so it runs over the spot.
SPOTS_B = dict(lat=[float(np.rad2deg(np.arcsin(0.3)))], lon=[0.0], radius=[10.0], contrast=[0.7],
               period=20.0, inc=90.0, t_ref=0.0, edge=2.0)
PLANET_B = jp.Planet(period=3.0, t0=0.0, a=8.0, inc=float(np.rad2deg(np.arccos(0.3 / 8.0))), radius=0.08)
# the planet wholly on the star (at the limb the window raster's own error,
# for the unspotted star too, is 1.2e-6 at its default pixel of r/16)
T_B = np.linspace(-0.05, 0.05, 5)


def test_spot_crossing_bump_matches_numpy_pixel_sum():
    system = jp.System(STAR.with_spots(**SPOTS_B), [PLANET_B])
    t = T_B
    f = np.asarray(system.flux(t))
    x, y, r = (np.asarray(v) for v in system.positions(t))
    ref = np.array([numpy_flux(SPOTS_B, tt, [(x[i, 0], y[i, 0], r[i, 0])]) for i, tt in enumerate(t)])
    bare = np.asarray(jp.System(STAR, [PLANET_B]).flux(t, method="exact"))
    spot_only = np.array([numpy_flux(SPOTS_B, tt) for tt in t])
    bump = ref - (bare - (1 - spot_only))  # light the planet does not block because the spot is dark
    assert bump.max() > 2e-3  # the bump is large here, so the check can fail
    # measured 4e-7; the numpy sum's own noise (linear edge coverage of the
    # planet), checked on the unspotted star against the exact engine, is
    # ~4e-7 at n = 2000
    assert np.max(np.abs(f - ref)) < 1e-6, np.max(np.abs(f - ref))


def test_auto_routes_spots_to_raster_and_exact_refuses():
    system = jp.System(STAR.with_spots(**SPOTS_B), [PLANET_B])
    t = T_B
    with pytest.raises(ValueError, match="radially symmetric"):
        system.flux(t, method="exact")
    x, y, r = system.positions(t)
    with pytest.raises(ValueError, match="needs the time of each frame"):
        jp.occultation_flux(system.star, x, y, r)
    auto = system.flux(t)  # System.flux passes its times to the spotted star
    ras = system.flux(t, method="raster", raster=RasterSettings(times=t))
    np.testing.assert_array_equal(np.asarray(auto), np.asarray(ras))
    # an alpha grid: the times broadcast over the [alpha, time] frames
    grid = np.asarray(system.flux(t, alpha=np.array([0.0, 90.0])))
    np.testing.assert_array_equal(grid[0], np.asarray(auto))
    assert grid.shape == (2, t.size)


def test_bad_spot_input():
    with pytest.raises(ValueError, match="radius"):
        Spots(lat=0.0, lon=0.0, radius=-1.0, contrast=0.5, period=10.0)
    with pytest.raises(ValueError, match="period"):
        Spots(lat=0.0, lon=0.0, radius=2.0, contrast=0.5, period=0.0)
    with pytest.raises(ValueError, match="lat"):
        Spots(lat=[95.0], lon=0.0, radius=2.0, contrast=0.5, period=10.0)
    with pytest.raises(ValueError, match="one value per spot"):
        Spots(lat=[0.0, 1.0], lon=[0.0, 1.0, 2.0], radius=2.0, contrast=0.5, period=10.0)
    with pytest.raises(ValueError, match="edge"):
        Spots(lat=0.0, lon=0.0, radius=2.0, contrast=0.5, period=10.0, edge=0.0)
    with pytest.raises(ValueError, match="contrast"):
        Spots(lat=0.0, lon=0.0, radius=2.0, contrast=1.5, period=10.0)


# ---- (c) gradients ----------------------------------------------------------------


def test_gradients_match_finite_differences():
    """d flux / d (radius, contrast, longitude) during a spot crossing,
    jax.grad against central differences (the pixel lattice does not move
    with the spot parameters, so the raster flux is smooth in them)."""
    system_planet = jp.System(STAR, [PLANET_B])
    t = T_B
    x, y, r = (np.asarray(v) for v in system_planet.positions(t))
    base = dict(SPOTS_B)

    def flux(p):
        kw = dict(base, radius=p[0:1], contrast=p[1:2], lon=p[2:3])
        return raster_flux(STAR.with_spots(**kw), x, y, r, times=t)

    p0 = jnp.array([10.0, 0.7, 3.0])
    jac = np.asarray(jax.jacfwd(flux)(p0))
    assert np.all(np.isfinite(jac))
    for j, h in enumerate((1e-3, 1e-4, 1e-3)):
        dp = jnp.zeros(3).at[j].set(h)
        fd = (np.asarray(flux(p0 + dp)) - np.asarray(flux(p0 - dp))) / (2 * h)
        assert np.max(np.abs(fd)) > 1e-5  # the parameter matters at these times
        np.testing.assert_allclose(jac[:, j], fd, rtol=1e-5, atol=1e-9)
