"""The pixel-grid method against the exact engine."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo import RasterSettings
from jaxppo.model._kepler20 import kepler20_system
from jaxppo.core.raster import pixel_disk_area


def _kepler20_ppo_frames():
    """Frames of Kepler-20 double transit 3 (BKJD 844.13) at alpha = 90 deg,
    where b occults c, plus frames with both planets apart."""
    system = kepler20_system()
    t = np.linspace(844.05, 844.22, 40)
    x, y, r = (np.asarray(v) for v in system.positions(jnp.asarray(t), 90.0, "same"))
    keep = (np.hypot(x, y) - r < 1).all(-1)
    return system.star, x[keep], y[keep], r[keep]


def test_pixel_disk_area_closed_form():
    assert abs(float(pixel_disk_area(-2.0, 2.0, -2.0, 2.0, 0.1, 0.2, 0.7)) - np.pi * 0.49) < 1e-14
    assert abs(float(pixel_disk_area(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0)) - np.pi / 4) < 1e-15
    # half plane x >= 0.5 of the unit disk: the circular segment
    seg = np.arccos(0.5) - 0.5 * np.sqrt(0.75)
    assert abs(float(pixel_disk_area(0.5, 2.0, -2.0, 2.0, 0.0, 0.0, 1.0)) - seg) < 1e-14


def test_window_default_within_1e7_on_kepler20():
    star, x, y, r = _kepler20_ppo_frames()
    exact = np.asarray(jp.occultation_flux(star, x, y, r, method="exact"))
    ras = np.asarray(jp.occultation_flux(star, x, y, r, method="raster"))
    assert (np.hypot(x[:, 0] - x[:, 1], y[:, 0] - y[:, 1]) < r.sum(1)).any()  # a PPO is in the set
    assert np.max(np.abs(ras - exact)) < 1e-7


def test_full_disk_converges_with_measured_order():
    star, x, y, r = _kepler20_ppo_frames()
    exact = np.asarray(jp.occultation_flux(star, x, y, r, method="exact"))
    errs = []
    ns = (64, 128, 256, 512)
    for n in ns:
        f = np.asarray(jp.occultation_flux(star, x, y, r, method="raster", raster=RasterSettings("full", n=n, ss=2)))
        errs.append(np.sqrt(np.mean((f - exact) ** 2)))
    order = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert errs[-1] < errs[0] / 4
    assert order > 1.0, (errs, order)


def test_window_converges_with_pixel_scale():
    star, x, y, r = _kepler20_ppo_frames()
    exact = np.asarray(jp.occultation_flux(star, x, y, r, method="exact"))
    errs = [np.max(np.abs(np.asarray(jp.occultation_flux(star, x, y, r, method="raster", raster=RasterSettings(scale=0.018 / d))) - exact)) for d in (4, 8, 16)]
    assert errs[2] < errs[1] < errs[0]


def test_surface_map_uses_raster_and_dims_the_star():
    star = jp.Star.quadratic(0.4, 0.26)
    spot = lambda x, y: 1.0 - 0.5 * ((x - 0.3) ** 2 + (y - 0.1) ** 2 < 0.05**2)
    spotted = star.with_surface(spot)
    assert not spotted.symmetric
    with pytest.raises(ValueError, match="radially symmetric"):
        jp.occultation_flux(spotted, [0.3], [0.1], [0.04], method="exact")
    # crossing the spot removes less light than crossing the bare star there
    on_spot = float(jp.occultation_flux(spotted, [0.3], [0.1], [0.04]))
    bare = float(jp.occultation_flux(star, [0.3], [0.1], [0.04]))
    assert on_spot > bare
    # away from the spot the spotted star behaves like the bare one, up to the
    # lower total flux (normalisation)
    away = float(jp.occultation_flux(spotted, [-0.5], [-0.3], [0.04]))
    assert away < 1.0


def test_bad_raster_settings():
    with pytest.raises(ValueError, match="raster mode"):
        RasterSettings(mode="sphere")
    with pytest.raises(ValueError, match="aa must be"):
        RasterSettings(mode="full", aa="exact")
    with pytest.raises(ValueError, match="pixel scale"):
        RasterSettings(scale=-1.0)


STAR_QD = jp.Star.quadratic(0.4, 0.26)


def _raster_vs_exact(x, y, r, **kw):
    x, y, r = (jnp.asarray(v, float) for v in (x, y, r))
    exact = np.asarray(jp.occultation_flux(STAR_QD, x, y, r, method="exact"))
    ras = np.asarray(jp.occultation_flux(STAR_QD, x, y, r, method="raster", raster=RasterSettings(**kw)))
    return ras, exact


def test_window_resolves_a_disk_of_nearly_the_stars_size():
    # the product of the disk's and the limb's pixel fractions counted a disk
    # edge just inside the limb as spread over the pixel (error 6e-3)
    ras, exact = _raster_vs_exact([[0.0], [0.005], [0.0]], [[0.0], [0.0], [0.004]], [[0.99], [0.99], [0.995]])
    assert np.max(np.abs(ras - exact)) < 1.5e-3, ras - exact
    ras4, _ = _raster_vs_exact([[0.0], [0.005], [0.0]], [[0.0], [0.0], [0.004]], [[0.99], [0.99], [0.995]], ss=4)
    assert np.max(np.abs(ras4 - exact)) < 2e-4, ras4 - exact


def test_window_disk_covering_the_star_gives_zero_never_negative():
    ras, exact = _raster_vs_exact([[0.0], [0.1], [0.0], [0.0]], [[0.0], [0.05], [0.0], [0.0]], [[1.2], [1.2], [0.999], [1.0]])
    assert np.all(ras >= 0.0), ras
    assert ras[0] == 0.0 and ras[1] == 0.0
    assert np.max(np.abs(ras - exact)) < 1.5e-3, ras - exact


def test_window_tiny_disk_next_to_a_large_one_is_bounded(monkeypatch):
    # the cost is bounded by construction: each disk's window has n_window + 2
    # pixels across, sized by that disk (a grid sized by the tiny disk over
    # the large one would need ~500^2 pixels). Checked on the windows the
    # raster uses (a wall-clock bound here failed on a loaded machine).
    from jaxppo.model import _raster

    sizes, window = [], _raster._window
    monkeypatch.setattr(_raster, "_window", lambda *a: sizes.append(a[8]) or window(*a))
    ras, exact = _raster_vs_exact([[0.3, -0.2]], [[0.0, 0.1]], [[1e-3, 0.5]])
    assert sizes == [RasterSettings().n_window + 2], sizes
    assert np.max(np.abs(ras - exact)) < 2e-5, ras - exact
    # the tiny disk is resolved on its own pixels: alone it is near exact
    ras, exact = _raster_vs_exact([[0.3]], [[0.0]], [[1e-3]])
    assert np.max(np.abs(ras - exact)) < 1e-12, ras - exact


def test_window_refuses_settings_over_the_memory_cap():
    x, y, r = (jnp.asarray(v, float) for v in ([[0.3, -0.2]], [[0.0, 0.1]], [[1e-3, 0.5]]))
    with pytest.raises(ValueError, match="RasterSettings.scale=1e-05"):
        jp.occultation_flux(STAR_QD, x, y, r, method="raster", raster=RasterSettings(scale=1e-5))
    with pytest.raises(ValueError, match="RasterSettings.n_window=5000"):
        RasterSettings(n_window=5000)
    with pytest.raises(ValueError, match="RasterSettings.n_window"):
        RasterSettings(n_window=4)
    with pytest.raises(ValueError, match="RasterSettings.n=20000"):
        jp.occultation_flux(STAR_QD, x, y, r, method="raster", raster=RasterSettings("full", n=20000))


@pytest.mark.parametrize("x,y,r,name", [
    ([np.nan], [0.0], [0.1], "x"),
    ([0.2], [np.inf], [0.1], "y"),
    ([0.2], [0.0], [-0.1], "r"),
    ([0.2], [0.0], [2e6], "r"),
])
def test_raster_checks_its_input_as_exact_does(x, y, r, name):
    """method="raster" skipped the concrete-input check: a NaN position or
    a negative radius gave 1.0, a radius of 2e6 gave 0.0. Every method now
    refuses them, naming the input (as "exact" and "auto" do)."""
    for method in ("raster", "exact", "auto"):
        with pytest.raises(ValueError, match=rf"\b{name}\b"):
            jp.occultation_flux(STAR_QD, jnp.asarray(x), jnp.asarray(y), jnp.asarray(r), method=method)


@pytest.mark.parametrize("r,kw,bound", [(0.03, {}, 2e-7), (0.1, {}, 2e-6), (0.5, {}, 1e-4), (0.99, {"ss": 4}, 1e-3)])
def test_raster_worst_over_positions(r, kw, bound):
    """The error RasterSettings documents is the worst over positions: one
    disk from the star's centre to past its limb (301 positions; the limb
    crossing is the worst place, where the old figures, taken at one
    position, were 2-10 times too small: 2e-5 documented at r = 0.5
    against 6.5e-5 measured there)."""
    x = np.linspace(0.0, 1.0 + r, 301)[:, None]
    ras, exact = _raster_vs_exact(x, np.zeros_like(x), np.full_like(x, r), **kw)
    assert np.max(np.abs(ras - exact)) <= bound, (r, float(np.max(np.abs(ras - exact))))


def test_docstrings_state_the_default_pixel_size():
    """Issue 24 item 12: occultation_flux's docstring said the raster pixel
    was "smallest radius / 24" while the code sizes each disk's pixels as
    its window (2 r for a disk inside the star) / n_window = r / 16."""
    from jaxppo.model import _flux

    from jaxppo.core import raster as R

    ratio = RasterSettings().n_window // 2
    # the code's pixel: the side of the disk's box on the star / n_window
    side = R.visible_box(np.array([[0.2]]), np.array([[0.1]]), np.array([[0.05]]), xp=np)[0]
    assert np.isclose(float(np.ravel(side)[0]) / RasterSettings().n_window, 0.05 / ratio, rtol=1e-12)
    for doc in (_flux.occultation_flux.__doc__, RasterSettings.__doc__):
        assert f"r / {ratio}" in " ".join(doc.split())
        assert "/ 24" not in doc and "smallest radius" not in doc
