"""PHOENIX SPECINT reader on a small file with the real layout, and the grids."""

import numpy as np
import pytest
from astropy.io import fits

import jaxppo as jp


def _write_specint(path, mu, wave0=3000.0, dwave=10.0, n_wave=800, profile=None, extname="MU", wcs=True):
    """A SPECINT-like file: primary HDU I[mu, lambda] with a linear WCS in
    Angstrom, mu values in an extension named MU (Husser et al. 2013 layout)."""
    wave = wave0 + dwave * np.arange(n_wave)
    prof = profile(mu) if profile is not None else 1 - 0.6 * (1 - mu)
    # a spectral shape that is not flat, so the passband weighting matters
    spec = 1.0 + 0.5 * np.sin(wave / 700.0)
    data = prof[:, None] * spec[None, :] * 1e14
    hdu = fits.PrimaryHDU(data)
    if wcs:
        hdu.header["CRVAL1"] = wave0
        hdu.header["CDELT1"] = dwave
        hdu.header["CRPIX1"] = 1.0
        hdu.header["CTYPE1"] = "AWAV"
    hdu.header["PHXTEFF"] = 5500.0
    hdu.header["PHXLOGG"] = 4.5
    hdus = [hdu]
    if extname is not None:
        hdus.append(fits.ImageHDU(mu, name=extname))
    fits.HDUList(hdus).writeto(path)
    return wave, spec


def test_reader_uses_file_axes(tmp_path):
    mu = np.linspace(0.01, 1, 50)[::-1]  # stored descending: the reader sorts
    wave, _ = _write_specint(tmp_path / "m.fits", mu)
    model = jp.read_specint(tmp_path / "m.fits")
    np.testing.assert_allclose(model.mu, np.sort(mu))
    np.testing.assert_allclose(model.wavelength, wave)
    assert model.intensity.shape == (50, 800)
    assert model.header["PHXTEFF"] == 5500.0


def test_band_integration_is_photon_weighted(tmp_path):
    mu = np.linspace(0.0, 1, 20)
    wave, spec = _write_specint(tmp_path / "m.fits", mu)
    model = jp.read_specint(tmp_path / "m.fits")
    wr, resp = jp.kepler_response()
    _, band = jp.band_intensity(model)
    r = np.interp(wave, wr, resp, left=0, right=0)
    expect = np.trapezoid(spec * r * wave, wave) * 1e14 * (1 - 0.6 * (1 - mu))
    np.testing.assert_allclose(band, expect, rtol=1e-12)
    _, band_e = jp.band_intensity(model, photon=False)
    assert not np.allclose(band_e / band_e[-1] * band[-1], band * 1.0001)


def test_spherical_limb_is_truncated_and_rescaled(tmp_path):
    """A spherical-model-like profile: the limb-darkened photosphere inside
    r_cri, a steep drop outside. After rescaling the star's edge is at r_cri."""
    r_cri = 0.99
    r = np.sort(np.concatenate([np.linspace(0, 0.999, 120), [r_cri]]))
    mu = np.sqrt(1 - r**2)[::-1]
    rr = np.sqrt(1 - mu**2)
    inside = rr <= r_cri
    mu_p = np.sqrt(np.clip(1 - (rr / r_cri) ** 2, 0, 1))
    prof = lambda m: np.where(inside, 1 - 0.6 * (1 - mu_p), 0.02 * np.exp(-(rr - r_cri) / 0.002))
    _write_specint(tmp_path / "sph.fits", mu, profile=prof)
    star = jp.phoenix_star(tmp_path / "sph.fits")
    mm = np.linspace(0, 1, 101)
    # the truncated, rescaled profile is the original law in mu'
    np.testing.assert_allclose(np.asarray(star.intensity(mm)), 1 - 0.6 * (1 - mm), atol=2e-3)
    m2, i2, mu_cri = jp.truncate_limb(mu, prof(mu))
    assert abs(np.sqrt(1 - mu_cri**2) - r_cri) < 1e-12


def test_grid_short_of_mu_0_loads_with_every_limb_method(tmp_path):
    """Star.tabulated refuses tables short of mu = 0 (issue 24 item 5);
    phoenix_star closes the gap as its limb method says."""
    mu = np.linspace(0.05, 1, 40)
    _write_specint(tmp_path / "m.fits", mu)
    for limb, at0 in (("none", 1 - 0.6 * 0.95), ("cut", 0.0), ("rescale", None)):
        star = jp.phoenix_star(tmp_path / "m.fits", limb=limb)
        assert float(star.mu_nodes[0]) == 0.0, limb
        if at0 is not None:
            np.testing.assert_allclose(float(star.params[0]), at0, rtol=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [(dict(wcs=False), "wavelength axis"), (dict(extname=None), "no mu axis")],
)
def test_reader_rejects_bad_layout(tmp_path, kwargs, match):
    _write_specint(tmp_path / "bad.fits", np.linspace(0.1, 1, 5), **kwargs)
    with pytest.raises(ValueError, match=match):
        jp.read_specint(tmp_path / "bad.fits")


def test_missing_file(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        jp.read_specint(tmp_path / "nope.fits")


def test_claret_grids():
    # Claret (2018) table 9 row logg 4.5, Teff 5500: a = 0.5046, b = 0.1752
    st = jp.claret_quadratic(5500, 4.5)
    np.testing.assert_allclose(np.asarray(st.params), [0.5046, 0.1752])
    mid = jp.claret_quadratic(5550, 4.5)
    lo, hi = np.asarray(st.params), np.asarray(jp.claret_quadratic(5600, 4.5).params)
    np.testing.assert_allclose(np.asarray(mid.params), 0.5 * (lo + hi))
    p2 = jp.claret_power2(5500, 4.5)
    np.testing.assert_allclose(np.asarray(p2.params), [0.71780284, 0.77644690])
    with pytest.raises(ValueError, match="teff=20000"):
        jp.claret_quadratic(20000, 4.5)


def test_default_star_is_p100():
    st = jp.kepler20_star()
    np.testing.assert_allclose(np.asarray(st.params), [1.0984732924, -1.74332475724, 2.46865245453, -0.995093958392])
