"""LightCurve loading, windows, normalisation and exposure integration."""

import numpy as np
import pytest
from astropy.io import fits

import jaxppo as jp
from jaxppo._phoenix import data_path


def _kepler_fits(path, columns=("TIME", "PDCSAP_FLUX", "PDCSAP_FLUX_ERR", "SAP_QUALITY"), quality=None):
    n = 50
    data = {"TIME": np.linspace(160, 161, n), "PDCSAP_FLUX": 1e5 + np.zeros(n), "PDCSAP_FLUX_ERR": np.full(n, 10.0),
            "SAP_QUALITY": np.zeros(n, int) if quality is None else quality}
    data["PDCSAP_FLUX"][3] = np.nan
    cols = [fits.Column(name=c, format="J" if c == "SAP_QUALITY" else "D", array=data[c]) for c in columns]
    hdu = fits.BinTableHDU.from_columns(cols, name="LIGHTCURVE")
    # the header values of a real Kepler long-cadence file (Q1, kplr006850504-2009166043257_llc.fits)
    hdu.header["INT_TIME"] = 6.019802903
    hdu.header["READTIME"] = 0.518948526
    hdu.header["FRAMETIM"] = 6.538751429
    hdu.header["NUM_FRM"] = 270
    hdu.header["TIMEDEL"] = 0.02043359821692
    hdu.header["DEADC"] = 0.92063492
    fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(path)


def test_kepler_fits_reader(tmp_path):
    q = np.zeros(50, int)
    q[[5, 6]] = 128
    _kepler_fits(tmp_path / "k.fits", quality=q)
    lc = jp.LightCurve.from_kepler_fits(tmp_path / "k.fits")
    assert lc.report["flagged"] == 2 and lc.report["non_finite"] == 1 and len(lc) == 47
    # A long cadence averages the flux over the cadence (29.42 min), not
    # over the summed photon time INT_TIME x NUM_FRM (27.09 min).
    assert abs(lc.exposure * 1440 - 29.4244) < 1e-3
    assert abs(lc.exposure - 6.538751429 * 270 / 86400) < 1e-8
    assert abs(np.median(lc.flux) - 1) < 1e-12


def test_kepler_fits_missing_columns(tmp_path):
    _kepler_fits(tmp_path / "k.fits", columns=("TIME", "PDCSAP_FLUX", "SAP_QUALITY"))
    with pytest.raises(ValueError, match="missing columns"):
        jp.LightCurve.from_kepler_fits(tmp_path / "k.fits")


def test_all_points_flagged(tmp_path):
    _kepler_fits(tmp_path / "k.fits", quality=np.full(50, 1))
    with pytest.raises(ValueError, match="no usable points"):
        jp.LightCurve.from_kepler_fits(tmp_path / "k.fits")


def test_real_csv_and_exposure_integration():
    lc = jp.LightCurve.from_csv(data_path("kepler20_kic6850504_q1_llc_BKJD159.0-161.5.csv"), exposure=0.02043357)
    assert lc.report == {**lc.report, "points": 122, "flagged": 7, "kept": 115}
    t, n = lc.supersampled_times()
    assert n % 2 == 1 and t.size == n * len(lc)
    # integrating a linear function over the exposure leaves it unchanged
    np.testing.assert_allclose(t.reshape(-1, n).mean(1), lc.time, atol=1e-12)
    # integration smooths a transit: the binned model is shallower at ingress
    system = jp.kepler20_system()
    inst = np.asarray(system.flux(lc.time))
    binned = np.asarray(system.flux(t)).reshape(-1, n).mean(1)
    assert np.max(np.abs(inst - binned)) > 1e-5


def test_normalisation_by_polynomial():
    t = np.linspace(0, 1, 200)
    trend = 1 + 0.01 * (t - 0.5) + 0.02 * (t - 0.5) ** 2
    dip = np.where(np.abs(t - 0.5) < 0.1, 0.999, 1.0)
    lc = jp.LightCurve(t, trend * dip, np.full(t.size, 1e-4))
    norm = lc.normalized([(0, 1)], in_transit=np.abs(t - 0.5) < 0.12)
    np.testing.assert_allclose(norm.flux, dip, atol=1e-10)


def test_bad_lightcurves(tmp_path):
    with pytest.raises(ValueError, match="flux_err must be > 0"):
        jp.LightCurve([1.0, 2.0], [1.0, 1.0], [0.1, 0.0])
    with pytest.raises(ValueError, match="exposure"):
        jp.LightCurve([1.0], [1.0], [0.1], exposure=-1)
    with pytest.raises(ValueError, match="not found"):
        jp.LightCurve.from_csv(tmp_path / "none.csv")


def _write(path, header, cols, gz=False):
    import gzip

    text = header + "\n" + "\n".join(",".join(f"{v:.10g}" for v in row) for row in zip(*cols)) + "\n"
    if gz:
        with gzip.open(path, "wt") as fh:
            fh.write(text)
    else:
        path.write_text(text)


def test_csv_column_names_gzip_and_estimated_errors(tmp_path):
    rng = np.random.default_rng(1)
    t = np.linspace(0, 5, 2000)
    f = 1 + rng.normal(0, 3e-4, t.size)
    _write(tmp_path / "a.csv", "bjd,rel_flux,error", (t, f, np.full(t.size, 3e-4)))
    lc = jp.LightCurve.from_csv(tmp_path / "a.csv", columns={"time": "bjd", "flux": "rel_flux", "flux_err": "error"})
    np.testing.assert_allclose(lc.flux, f, rtol=0, atol=1e-9)  # not renormalised (10 digits written)
    assert not lc.errors_estimated
    with pytest.raises(ValueError, match=r"columns.flux_err = 'sigma_f' is not a column"):
        jp.LightCurve.from_csv(tmp_path / "a.csv", columns={"time": "bjd", "flux": "rel_flux", "flux_err": "sigma_f"})
    with pytest.raises(ValueError, match="unknown role 'fluxerr'"):
        jp.LightCurve.from_csv(tmp_path / "a.csv", columns={"fluxerr": "error"})
    # gzip, no error column: the error comes from the scatter (white noise 3e-4 here)
    _write(tmp_path / "b.csv.gz", "time,flux", (t, f), gz=True)
    lc = jp.LightCurve.from_csv(tmp_path / "b.csv.gz")
    assert lc.errors_estimated and "estimated" in lc.report["flux_err"]
    assert abs(lc.flux_err[0] / 3e-4 - 1) < 0.05


def test_quarters_normalised_separately(tmp_path):
    t = np.arange(0, 20, 0.02)
    q = np.where(t < 10, 1, 2)
    level = np.where(q == 1, 1.5e5, 0.9e5)
    _write(tmp_path / "q.csv", "time_bkjd,pdcsap_flux,quarter", (t, level * (1 + 1e-4 * np.sin(t * 7)), q))
    lc = jp.LightCurve.from_csv(tmp_path / "q.csv")
    assert abs(np.median(lc.flux[lc.time < 10]) - 1) < 1e-5 and abs(np.median(lc.flux[lc.time > 10]) - 1) < 1e-5
    assert set(lc.report["divided_by"]) == {"1", "2"}
    # the same as two files, one per quarter
    for k in (1, 2):
        m = q == k
        _write(tmp_path / f"q{k}.csv", "time_bkjd,pdcsap_flux,pdcsap_flux_err", (t[m], level[m] * (1 + 1e-4 * np.sin(t[m] * 7)), 10 + 0 * t[m]))
    both = jp.LightCurve.concatenate([jp.LightCurve.from_csv(tmp_path / f"q{k}.csv") for k in (1, 2)])
    np.testing.assert_allclose(both.flux, lc.flux, rtol=1e-12)
    with pytest.raises(ValueError, match="share 500 time stamps"):
        jp.LightCurve.concatenate([jp.LightCurve.from_csv(tmp_path / "q1.csv")] * 2)
