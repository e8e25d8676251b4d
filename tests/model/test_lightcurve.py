"""LightCurve loading, windows, normalisation and exposure integration."""

import warnings

import numpy as np
import pytest
from astropy.io import fits

import jaxppo as jp
from jaxppo.model._phoenix import data_path

# One cadence of each mission's light-curve files; quality values (bits):
# Kepler 1 attitude tweak, 128 cosmic ray in the aperture, 8192 cosmic ray in
# collateral data, 65536 no data (Kepler Archive Manual Table 2-3); in TESS
# files 128 is "manual exclude" and 512 "impulsive outlier" (TESS SDPDD
# Table 28). Written at rows 5..9 below.
_FLAGS = {5: 1, 6: 128, 7: 8192, 8: 65536, 9: 512}


def _lc_fits(path, mission="kepler", columns=None, quality=None, telescop=True, n=50):
    """A light-curve FITS file with the layout of the archive's files:
    primary header TELESCOP / CREATOR, extension LIGHTCURVE with TIME (BKJD or
    BTJD), SAP/PDCSAP flux [e-/s] with errors and the quality column
    (SAP_QUALITY for Kepler, QUALITY for TESS); header values of a real
    Kepler long-cadence file (Q1, kplr006850504-2009166043257_llc.fits) or of
    a TESS SPOC 2-minute file."""
    kepler = mission == "kepler"
    qname = "SAP_QUALITY" if kepler else "QUALITY"
    t = np.linspace(160, 161, n) if kepler else np.linspace(1683.0, 1684.0, n)
    q = np.zeros(n, int)
    if quality is None:
        for i, v in _FLAGS.items():
            q[i] = v
    else:
        q = quality
    flux = 1e5 + 10 * np.sin(np.arange(n))
    flux[3] = np.nan
    t[20] = t[19]  # a repeated cadence
    data = {"TIME": t, "SAP_FLUX": flux * 1.1, "SAP_FLUX_ERR": np.full(n, 11.0), "PDCSAP_FLUX": flux,
            "PDCSAP_FLUX_ERR": np.full(n, 10.0), qname: q}
    columns = columns or tuple(data)
    units = {"TIME": "BJD - 2454833" if kepler else "BJD - 2457000, days", qname: None}
    cols = [fits.Column(name=c, format="J" if c == qname else "D", array=data[c], unit=units.get(c, "e-/s"))
            for c in columns]
    hdu = fits.BinTableHDU.from_columns(cols, name="LIGHTCURVE")
    prim = fits.PrimaryHDU()
    if telescop:
        prim.header["TELESCOP"] = "Kepler" if kepler else "TESS"
    prim.header["CREATOR"] = "FluxExporter2PipelineModule" if kepler else "LightCurveExporterPipelineModule"
    prim.header["ORIGIN"] = "NASA/Ames"
    prim.header["OBJECT"] = "KIC 6850504" if kepler else "TIC 12345"
    if kepler:
        hdu.header["INT_TIME"] = 6.019802903
        hdu.header["READTIME"] = 0.518948526
        hdu.header["FRAMETIM"] = 6.538751429
        hdu.header["NUM_FRM"] = 270
        hdu.header["TIMEDEL"] = 0.02043359821692
        hdu.header["DEADC"] = 0.92063492
        hdu.header["BJDREFI"], hdu.header["BJDREFF"] = 2454833, 0.0
    else:
        hdu.header["TIMEDEL"] = 0.001388888888888889
        hdu.header["BJDREFI"], hdu.header["BJDREFF"] = 2457000, 0.0
    hdu.header["TIMESYS"] = "TDB"
    fits.HDUList([prim, hdu]).writeto(path)
    return data


def test_kepler_fits_default_bitmask_and_report(tmp_path):
    """The old reader dropped every flagged cadence (cosmic-ray flags too, and
    silently merged nothing): the default bitmask drops only the unusable
    ones, and every dropped point is counted."""
    _lc_fits(tmp_path / "k.fits")
    lc = jp.LightCurve.from_fits(tmp_path / "k.fits")
    r = lc.report
    # dropped: 1 (attitude tweak) and 65536 (no data); kept: 128, 8192, 512 (unused)
    assert (r["flagged"], r["flags_kept"], r["non_finite"], r["duplicated"]) == (2, 3, 1, 1)
    assert len(lc) == 50 - 4 and r["kept"] == 46 and r["mission"] == "kepler"
    assert r["quality_bitmask"] == 1130799  # lightkurve's KeplerQualityFlags.DEFAULT_BITMASK
    assert "BKJD" in r["time"] and "2454833" in r["time"]
    assert "46 of 50 points" in lc.report_line() and "1 repeated time stamps" in lc.report_line()
    # time kept in BKJD: the first row is BKJD 160 exactly
    assert lc.time[0] == 160.0
    # A long cadence averages the flux over the cadence (29.42 min), not
    # over the summed photon time INT_TIME x NUM_FRM (27.09 min).
    assert abs(lc.exposure * 1440 - 29.4244) < 1e-3
    assert abs(lc.exposure - 6.538751429 * 270 / 86400) < 1e-8
    assert abs(np.median(lc.flux) - 1) < 1e-4
    hard = jp.LightCurve.from_fits(tmp_path / "k.fits", quality_bitmask="hard")
    assert hard.report["flagged"] == 4  # + both cosmic-ray flags
    assert jp.LightCurve.from_fits(tmp_path / "k.fits", quality_bitmask="hardest").report["flagged"] == 4
    assert jp.LightCurve.from_fits(tmp_path / "k.fits", quality_bitmask="none").report["flagged"] == 0
    assert jp.LightCurve.from_fits(tmp_path / "k.fits", quality_bitmask=128).report["flagged"] == 1
    # from_kepler_fits is from_fits for Kepler files
    np.testing.assert_array_equal(jp.LightCurve.from_kepler_fits(tmp_path / "k.fits").time, lc.time)


def test_tess_spoc_fits(tmp_path):
    """TESS files: QUALITY column, BTJD, 2-minute exposure, and the TESS
    meaning of the bits (128 is "manual exclude", dropped; 512 "impulsive
    outlier", dropped; 8192 "planet search exclude", kept)."""
    _lc_fits(tmp_path / "t.fits", mission="tess")
    lc = jp.LightCurve.from_fits(tmp_path / "t.fits")
    r = lc.report
    assert r["mission"] == "tess" and r["quality_bitmask"] == 17087  # lightkurve's TessQualityFlags.DEFAULT_BITMASK
    assert (r["flagged"], r["flags_kept"], r["non_finite"], r["duplicated"]) == (3, 2, 1, 1)
    assert "BTJD" in r["time"] and lc.time[0] == 1683.0
    assert abs(lc.exposure * 1440 - 2.0) < 1e-9
    # a Kepler reader would have kept the manual exclude (its bit 128 is a cosmic ray)
    kep = jp.LightCurve.from_fits(tmp_path / "t.fits", mission="kepler")
    assert kep.report["flagged"] == 2


def test_fits_errors(tmp_path):
    _lc_fits(tmp_path / "k.fits", columns=("TIME", "PDCSAP_FLUX", "SAP_QUALITY"))
    with pytest.raises(ValueError, match="missing columns"):
        jp.LightCurve.from_fits(tmp_path / "k.fits")
    _lc_fits(tmp_path / "n.fits", telescop=False)
    with pytest.raises(ValueError, match="no TELESCOP or MISSION keyword; pass mission="):
        jp.LightCurve.from_fits(tmp_path / "n.fits")
    assert len(jp.LightCurve.from_kepler_fits(tmp_path / "n.fits")) == 46
    _lc_fits(tmp_path / "a.fits", quality=np.full(50, 1))
    with pytest.raises(ValueError, match="no usable points"):
        jp.LightCurve.from_fits(tmp_path / "a.fits")
    with pytest.raises(ValueError, match="quality_bitmask must be"):
        jp.LightCurve.from_fits(tmp_path / "n.fits", quality_bitmask="strict", mission="kepler")
    with pytest.raises(ValueError, match="folder"):
        jp.LightCurve.from_fits(tmp_path)


def test_bitmasks_match_lightkurve():
    import lightkurve as lk  # in the test extra: a missing install fails, not skips
    from jaxppo.model._lightcurve import QUALITY_BITMASKS

    for mission, flags in (("kepler", lk.utils.KeplerQualityFlags), ("tess", lk.utils.TessQualityFlags)):
        for name in ("none", "default", "hard", "hardest"):
            assert QUALITY_BITMASKS[mission][name] == flags.OPTIONS[name], (mission, name)


def test_from_lightkurve(tmp_path):
    """lightkurve is optional: imported by the test only. Its reader drops
    its own default bitmask (and rows with NaN time) before jaxppo sees the
    data; read with quality_bitmask='none', jaxppo's default gives exactly
    from_fits."""
    import lightkurve as lk  # in the test extra: a missing install fails, not skips
    _lc_fits(tmp_path / "k.fits")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = lk.read(str(tmp_path / "k.fits"), quality_bitmask="none")
        dflt = lk.read(str(tmp_path / "k.fits"))
    assert raw.time.format == "bkjd"
    ref = jp.LightCurve.from_fits(tmp_path / "k.fits")
    got = jp.LightCurve.from_lightkurve(raw)
    np.testing.assert_array_equal(got.time, ref.time)
    np.testing.assert_allclose(got.flux, ref.flux, rtol=1e-14)
    np.testing.assert_allclose(got.flux_err, ref.flux_err, rtol=1e-14)
    assert got.exposure == ref.exposure
    r = got.report
    assert (r["flagged"], r["non_finite"], r["duplicated"], r["quality_bitmask"]) == (2, 1, 1, 1130799)
    assert "BKJD" in r["time"]
    # the default-read light curve: lightkurve already dropped the 2 flagged rows
    got2 = jp.LightCurve.from_lightkurve(dflt)
    np.testing.assert_array_equal(got2.time, ref.time)
    assert got2.report["points"] == 48 and got2.report["lightkurve_quality_bitmask"] == "default"
    # a normalised (dimensionless) flux is taken as it is; SAP flux by name
    norm = jp.LightCurve.from_lightkurve(raw.normalize())
    assert "divided_by" in norm.report and norm.report["divided_by"] == 1.0
    sap = jp.LightCurve.from_lightkurve(raw, flux_column="sap_flux")
    np.testing.assert_allclose(sap.flux, ref.flux * 1.1 / np.median(ref.flux * 1.1) * np.median(ref.flux), rtol=1e-12)
    with pytest.raises(ValueError, match="flux_column 'kspsap_flux' is not a column"):
        jp.LightCurve.from_lightkurve(raw, flux_column="kspsap_flux")
    # jp.scan takes the lightkurve object directly
    from jaxppo.obliquity._config import config_from_arguments

    cfg = config_from_arguments(jp.kepler20_system(), raw, None, ("same",), 0.05, 2, 0.3, 5.0, None, 60)
    np.testing.assert_array_equal(cfg.lightcurve.time, ref.time)
    assert cfg.lightcurve.report["flagged"] == 2


def test_astropy_time_and_quantity_columns():
    """Time and Quantity inputs: the old constructor took the Quantity's
    number in whatever unit it had (hours as days) and could not take a
    Time at all."""
    import astropy.units as u
    from astropy.time import Time

    bkjd = np.array([160.0, 160.5, 161.0])
    t = Time(bkjd + 2454833.0, format="jd", scale="tdb")
    with pytest.raises(ValueError, match="set time_zero"):
        jp.LightCurve(t, np.ones(3), np.full(3, 1e-3))
    lc = jp.LightCurve(t, np.ones(3), np.full(3, 1e-3), time_zero=2454833.0)
    np.testing.assert_allclose(lc.time, bkjd, rtol=0, atol=1e-9)  # 0.1 ms
    assert "BJD_TDB - 2454833.0 [d] (BKJD)" in lc.report["time"]
    # a UTC Time is moved to TDB (TDB - UTC = 32.184 s + 34 leap seconds in 2009)
    utc = jp.LightCurve(Time(bkjd + 2454833.0, format="jd", scale="utc"), np.ones(3), np.full(3, 1e-3),
                        time_zero=2454833.0)
    np.testing.assert_allclose((utc.time - bkjd) * 86400, 66.184, atol=2e-3)
    # BTJD-style zero point from a TESS time
    tess = jp.LightCurve(Time([2459683.0, 2459684.0], format="jd", scale="tdb"), [1.0, 1.0], [1e-3, 1e-3],
                         time_zero=2457000.0)
    np.testing.assert_allclose(tess.time, [2683.0, 2684.0], atol=1e-9)
    assert "(BTJD)" in tess.report["time"]
    # time Quantities in hours, flux in ppm-relative units
    q = jp.LightCurve([0, 12, 24] * u.h, [1.0, 1.0, 1.0] * u.dimensionless_unscaled, [0.01, 0.01, 0.01] * u.percent)
    np.testing.assert_allclose(q.time, [0, 0.5, 1.0])
    np.testing.assert_allclose(q.flux_err, 1e-4)
    with pytest.raises(ValueError, match="unit electron / s.*from_arrays"):
        jp.LightCurve(bkjd, [1e5, 1e5, 1e5] * u.electron / u.s, [10, 10, 10] * u.electron / u.s)
    # raw e-/s: from_arrays divides by the median, drops and reports NaN and flagged points
    raw = jp.LightCurve.from_arrays(Time(np.r_[bkjd, 161.5] + 2454833.0, format="jd", scale="tdb"),
                                    [2e5, 2.2e5, np.nan, 2e5] * u.electron / u.s, [20, 20, 20, 20] * u.electron / u.s,
                                    quality=[0, 0, 0, 32], mission="kepler", time_zero=2454833.0)
    np.testing.assert_allclose(raw.flux, [2.0 / 2.1, 2.2 / 2.1])  # median of the kept points: 2.1e5
    np.testing.assert_allclose(raw.flux_err, 20 / 2.1e5)
    assert (raw.report["flagged"], raw.report["non_finite"]) == (1, 1)
    with pytest.raises(ValueError, match="does not convert"):
        jp.LightCurve.from_arrays(bkjd * u.m, [1.0] * 3, [1e-3] * 3)


def test_exposure_quantity_is_stored_in_days():
    """Issue 24 item 6: exposure=30 * u.min was stored as the Quantity and
    the fit then failed with an unrelated TypeError; it is 30 / 1440 d."""
    import astropy.units as u
    from astropy.time import TimeDelta

    t = np.linspace(0.0, 1.0, 5)
    for exp in (30 * u.min, TimeDelta(1800.0 * u.s), 0.5 * u.h):
        lc = jp.LightCurve(t, np.ones(5), np.full(5, 1e-3), exposure=exp)
        assert type(lc.exposure) is float and abs(lc.exposure - 30 / 1440) < 1e-15
        times, n = lc.supersampled_times()
        np.testing.assert_allclose(np.ptp(times.reshape(5, n), axis=1), 30 / 1440 * (n - 1) / n, rtol=1e-12)
    lc = jp.LightCurve.from_arrays(t, np.ones(5), np.full(5, 1e-3), exposure=30 * u.min)
    assert type(lc.exposure) is float and abs(lc.exposure - 30 / 1440) < 1e-15
    with pytest.raises(ValueError, match="exposure must be a time, got the Quantity"):
        jp.LightCurve(t, np.ones(5), np.full(5, 1e-3), exposure=30 * u.m)
    with pytest.raises(ValueError, match="exposure must be >= 0 days"):
        jp.LightCurve(t, np.ones(5), np.full(5, 1e-3), exposure=-1 * u.min)
    with pytest.raises(ValueError, match="exposure must be one number of days"):
        jp.LightCurve(t, np.ones(5), np.full(5, 1e-3), exposure=[1, 2] * u.min)


def test_an_exposure_in_minutes_read_as_days_is_refused():
    """exposure = 29.4 (minutes, read as days) on a 29.4-min cadence averaged the model over a month and the
    scan asked for 40.9 GiB ("internal error: MemoryError"); an exposure longer than twice the points' median
    spacing is refused, naming it; one as long as the spacing (Kepler long cadence) is fine."""
    t = 100.0 + np.arange(50) * 0.0204336
    ok = jp.LightCurve(t, np.ones(50), np.full(50, 1e-3), exposure=0.0204336)
    assert ok.exposure == 0.0204336
    jp.LightCurve(t[::5], np.ones(10), np.full(10, 1e-3), exposure=0.0204336)  # every fifth point: shorter
    for bad in (29.4, 1765.0, 0.49):  # minutes, seconds, hours read as days
        with pytest.raises(ValueError, match=rf"exposure must be a number of days no longer than the points' "
                                             rf"spacing, got {bad:g} d, .* median spacing of 0.0204336 d"):
            jp.LightCurve(t, np.ones(50), np.full(50, 1e-3), exposure=bad)


def test_repeated_time_stamps_are_never_silent():
    """The old constructor accepted the same cadence twice (it would count
    twice in chi^2); now it refuses, and the loaders drop and count it."""
    with pytest.raises(ValueError, match="1 repeated time stamps"):
        jp.LightCurve([1.0, 2.0, 2.0], [1.0, 1.0, 1.0], [0.1, 0.1, 0.1])
    lc = jp.LightCurve.from_arrays([1.0, 2.0, 2.0, 3.0], [1.0, 1.1, 1.2, 1.0], [0.1] * 4, normalize=False)
    np.testing.assert_allclose(lc.flux, [1.0, 1.1, 1.0])  # the first of the pair is kept
    assert lc.report["duplicated"] == 1 and "1 repeated time stamps" in lc.report_line()


def test_csv_quality_bitmask(tmp_path):
    """A CSV has no mission: every flag drops the point (the report says
    so); with mission='kepler' the default bitmask keeps the cosmic-ray
    flags of the bundled Q1 file (3 x 128, 4 x 8192)."""
    path = data_path("kepler20_kic6850504_q1_llc_BKJD159.0-161.5.csv")
    lc = jp.LightCurve.from_csv(path)
    assert lc.report["flagged"] == 7 and "mission unknown" in lc.report["quality_bitmask_name"]
    kep = jp.LightCurve.from_csv(path, mission="kepler")
    assert kep.report["flagged"] == 0 and kep.report["flags_kept"] == 7 and len(kep) == 122
    assert jp.LightCurve.from_csv(path, mission="kepler", quality_bitmask="hard").report["flagged"] == 7


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


def test_missing_flux_err_is_named():
    """LightCurve(time, flux, None) raised "AttributeError: 'NoneType'
    object has no attribute 'shape'"; it now says flux_err is needed and
    where errors are estimated."""
    with pytest.raises(ValueError, match=r"flux_err must be given .*from_arrays"):
        jp.LightCurve([1.0, 2.0], [1.0, 1.0], None)


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


def test_csv_empty_cells_are_counted(tmp_path):
    """Read with astropy's CSV reader: an empty flux cell is dropped as
    non-finite, an empty quality cell as flagged, and a word where a number
    belongs names its row and column."""
    (tmp_path / "e.csv").write_text("# a comment line\ntime,flux,flux_err,quality\n1,1.0,0.1,0\n2,,0.1,0\n3,1.0,0.1,\n"
                                    "4,1.02,0.1,0\n")
    lc = jp.LightCurve.from_csv(tmp_path / "e.csv")
    assert (lc.report["non_finite"], lc.report["flagged"], len(lc)) == (1, 1, 2)
    np.testing.assert_array_equal(lc.time, [1.0, 4.0])
    (tmp_path / "w.csv").write_text("time,flux\n1,1.0\n2,abc\n")
    with pytest.raises(ValueError, match=r"unreadable row 2 in column 'flux': 'abc' is not a number"):
        jp.LightCurve.from_csv(tmp_path / "w.csv")
    (tmp_path / "h.csv").write_text("time,flux\n")
    with pytest.raises(ValueError, match="needs a header and at least one row"):
        jp.LightCurve.from_csv(tmp_path / "h.csv")


def test_the_exposure_rule():
    """One home (jaxppo.model._exposure): LightCurve.supersampled_times is
    supersampled_times of its time and exposure; exposure_mean averages each
    cadence's sub-exposures (NumPy and JAX); n and exposure are checked."""
    import jax.numpy as jnp

    from jaxppo.model._exposure import SUB_EXPOSURE, exposure_mean, sub_exposures, supersampled_times

    t = np.array([1.0, 1.5, 2.25])
    lc = jp.LightCurve(t, np.ones(3), np.full(3, 1e-4), exposure=0.0204)
    got, n = lc.supersampled_times()
    assert n == sub_exposures(0.0204) == 59 and n % 2 == 1 and 0.0204 / n <= SUB_EXPOSURE
    ref, n_ref = supersampled_times(t, 0.0204)
    assert n_ref == n and np.array_equal(got, ref)
    # the midpoint of every cadence is a sub-exposure; the mean of t is t
    np.testing.assert_allclose(exposure_mean(got, n), t, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.asarray(exposure_mean(jnp.asarray(got), n)), t, rtol=0, atol=1e-15)
    assert np.array_equal(exposure_mean(np.stack([got, 2 * got]), n), np.stack([exposure_mean(got, n),
                                                                               exposure_mean(2 * got, n)]))
    assert supersampled_times(t, None)[1] == 1 and lc.supersampled_times(3)[1] == 3
    with pytest.raises(ValueError, match="n \\(sub-exposures"):
        lc.supersampled_times(0)
    with pytest.raises(ValueError, match="exposure"):
        sub_exposures(-1.0)


def test_csv_with_a_byte_order_mark(tmp_path):
    """A spreadsheet's UTF-8 export starts with a byte-order mark: it was read
    as part of the first column's name ("no time column ... '\\ufefftime'")."""
    path = tmp_path / "bom.csv"
    path.write_bytes("time,flux,flux_err\n1.0,1.0,0.001\n1.1,0.999,0.001\n".encode("utf-8-sig"))
    lc = jp.LightCurve.from_csv(path)
    np.testing.assert_array_equal(lc.time, [1.0, 1.1])


@pytest.mark.parametrize("text", [
    None,  # the bundled real Kepler-20 Q1-Q17 file (gzip)
    "# c\ntime,flux\r\n1,2\r\n\r\n3,4\r\n",
    "Time , FLUX,flux_err,quality\n 1.5 , 2e-3,nan,0\n3,inf,1,128\n",
    "time,flux\n1,2\n3\n",  # ragged
    "time,flux\n1,\n3,4\n",  # an empty cell
    "time,flux\n1,2 # x\n",  # not a number
    "time,flux\n\n",  # no rows
    'time,"flux"\n1,2\n',  # a quoted name
    "time,flux\n1,2\x0b3,4\n",  # a vertical tab (str.splitlines broke the row in two; astropy refuses it)
    "time,flux\n1,2\u20283,4\n",  # a Unicode line separator
])
def test_csv_read_by_numpy_equals_astropy(tmp_path, text, monkeypatch):
    """Plain numeric CSV files are parsed by numpy (20 ms for the bundled
    Kepler-20 rows, astropy's reader 54 ms plus 0.3 s to import): the same
    columns as astropy's reader, or the same error, whichever reader a file
    takes."""
    from jaxppo.model import _readers

    path = data_path("kepler20_kic6850504_llc_q1-q17_pdcsap.csv.gz") if text is None else tmp_path / "x.csv"
    if text is not None:
        path.write_bytes(text.encode())

    def read():
        try:
            return _readers.read_csv_columns(path, {})
        except ValueError as err:
            return str(err)

    fast = read()
    monkeypatch.setattr(_readers, "_plain_csv", lambda text: None)
    slow = read()
    if isinstance(slow, str):
        assert fast == slow
        return
    assert fast[-1] == slow[-1]
    for a, b in zip(fast[:-1], slow[:-1]):
        assert (a is None) == (b is None)
        if a is not None:
            assert a.dtype == b.dtype == float
            np.testing.assert_array_equal(a, b)
    if text is None:
        assert fast[0].size == 64792


def test_to_time_zero_moves_between_kepler_and_tess_time():
    """BTJD -> BKJD is +2167 d exactly; the zero point comes from the light
    curve (time_zero, or its mission) or from ``current``; unknown ones and
    bad names are refused by name."""
    import jaxppo as jp

    lc = jp.LightCurve(np.array([1689.0, 1690.0]), np.ones(2), np.full(2, 1e-3))
    with pytest.raises(ValueError, match="time zero point is unknown"):
        lc.to_time_zero("bkjd")
    bk = lc.to_time_zero("bkjd", current="btjd")
    assert np.array_equal(bk.time, lc.time + 2167.0) and bk.time_zero == 2454833.0
    back = bk.to_time_zero("btjd")
    assert np.array_equal(back.time, lc.time) and "BTJD" in back.report["time"]
    assert np.array_equal(bk.to_time_zero(2454000.0).time, lc.time + 3000.0)
    with pytest.raises(ValueError, match="time_zero must be 'bkjd', 'btjd' or a Julian date, got 'mjd'"):
        bk.to_time_zero("mjd")
    with pytest.raises(ValueError, match="current must be finite"):
        lc.to_time_zero("bkjd", current=float("nan"))


def test_selections_keep_the_time_zero():
    """A selection of a shifted light curve keeps its zero point: a second
    to_time_zero must not apply the mission's shift again (it gave +4334 d)."""
    import jaxppo as jp

    lc = jp.LightCurve(np.array([1689.0, 1690.0, 1691.0]), np.ones(3), np.full(3, 1e-3), report={"mission": "tess"})
    bk = lc.to_time_zero("bkjd")
    for part in (bk.select(np.array([True, True, False])), bk.windows([(3855.0, 3857.5)]),
                 bk):
        assert part.time_zero == 2454833.0
        assert np.array_equal(part.to_time_zero("bkjd").time, part.time)
    with pytest.raises(ValueError, match="time_zero must be 'bkjd', 'btjd' or a Julian date, got True"):
        bk.to_time_zero(True)


def test_negative_errors_are_reported_as_such():
    """Issue 24 item 10: a negative error was counted and reported as
    "non-finite"; the report and the constructor's refusal say "error <= 0"."""
    t = np.linspace(0.0, 1.0, 6)
    lc = jp.LightCurve.from_arrays(t, np.ones(6), np.array([1e-3, -1e-3, 1e-3, 0.0, 1e-3, 1e-3]))
    assert len(lc) == 4 and lc.report["non_finite"] == 2
    assert "2 non-finite or with error <= 0" in lc.report_line()
    with pytest.raises(ValueError, match=r"flux_err must be > 0, found -0.001"):
        jp.LightCurve(t, np.ones(6), np.array([1e-3, -1e-3, 1e-3, 1e-3, 1e-3, 1e-3]))


def test_concatenating_instruments_of_different_exposures():
    """Kepler (29.4 min) and TESS (2 min) points joined with one exposure
    were averaged over the wrong length without a word."""
    tk, tt = np.arange(98) * 0.0204, 10.0 + np.arange(40) * 0.0014
    kep = jp.LightCurve(tk, np.ones(tk.size), np.full(tk.size, 1e-4), exposure=0.0204)
    tess = jp.LightCurve(tt, np.ones(tt.size), np.full(tt.size, 1e-4), exposure=0.0014)
    with pytest.raises(ValueError, match=r"different exposures \[0.0014, 0.0204\] \[d\]: a light curve has one"):
        jp.LightCurve.concatenate([kep, tess])
    with pytest.warns(UserWarning, match=r"parts with exposures \[0.0014\] \[d\] are modelled with exposure = 0.0204"):
        jp.LightCurve.concatenate([kep, tess], exposure=0.0204)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the same length to rounding: no warning
        jp.LightCurve.concatenate([kep], exposure=0.0204 * (1 + 1e-6))


def test_concatenate_refuses_mixed_time_zero_points():
    """A BTJD light curve joined to a BKJD one was taken as is: its points sat
    2167 d off, every transit in the wrong place, without a word. The zero
    points (time_zero, a Kepler / TESS file's, an astropy Time's) are now
    compared, kept through concatenate, and known for lightkurve-style
    Time inputs (to_time_zero needed current= for a BTJD Time)."""
    import lightkurve  # noqa: F401  (registers astropy's "btjd" Time format)
    from astropy.time import Time

    tt = 1689.0 + np.arange(40) * 0.0014
    tess = jp.LightCurve(tt, np.ones(tt.size), np.full(tt.size, 1e-3), exposure=0.0014, report={"mission": "tess"})
    bk = tess.to_time_zero("bkjd")
    later = jp.LightCurve(tt + 30.0, np.ones(tt.size), np.full(tt.size, 1e-3), exposure=0.0014,
                          time_zero=2454833.0)
    with pytest.raises(ValueError, match=r"different zero points, BJD_TDB - 2454833.0 \(BKJD\), 2457000.0 \(BTJD\)"):
        jp.LightCurve.concatenate([tess, later])
    both = jp.LightCurve.concatenate([bk, later])
    assert both.time_zero == 2454833.0 and "(BKJD)" in both.report["time"]
    np.testing.assert_allclose(both.to_time_zero("btjd").time[-tt.size:], tt, rtol=0, atol=1e-9)
    unknown = jp.LightCurve(tt + 60.0, np.ones(tt.size), np.full(tt.size, 1e-3), exposure=0.0014)
    with pytest.warns(UserWarning, match=r"part\(s\) \[1\] have no known time zero point .* BJD_TDB - 2454833.0 \(BKJD\)"):
        assert jp.LightCurve.concatenate([bk, unknown]).time_zero is None  # one part's zero is not known
    declared = unknown.to_time_zero("bkjd", current="bkjd")
    assert np.array_equal(declared.time, unknown.time)
    assert jp.LightCurve.concatenate([bk, declared]).time_zero == 2454833.0
    # an astropy Time in BTJD carries its zero point
    t = jp.LightCurve.from_arrays(Time(tt, format="btjd", scale="tdb"), np.ones(tt.size), np.full(tt.size, 1e-3))
    assert t.time_zero == 2457000.0
    np.testing.assert_allclose(t.to_time_zero("bkjd").time, tt + 2167.0, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="different zero points"):
        jp.LightCurve.concatenate([t, later])


def test_concatenate_select_windows_name_bad_inputs():
    """Bad inputs gave AttributeError, TypeError or numpy's IndexError; now a
    ValueError that names the argument."""
    t = np.arange(10) * 0.0014
    lc = jp.LightCurve(t, np.ones(10), np.full(10, 1e-3))
    with pytest.raises(ValueError, match="concatenate: part 1 must be a jaxppo LightCurve, got NoneType"):
        jp.LightCurve.concatenate([lc, None])
    with pytest.raises(ValueError, match="a list of light curves, got one light curve"):
        jp.LightCurve.concatenate(lc)
    with pytest.raises(ValueError, match=r"mask must hold one bool per point, shape \(10,\), got shape \(5,\)"):
        lc.select(np.ones(5, bool))
    with pytest.raises(ValueError, match=r"intervals must be \(start, end\) pairs"):
        lc.windows((0.0, 0.005))
    assert len(lc.windows([(0.0, 0.005)])) == 4
    with pytest.raises(ValueError, match="path must be one file, got a list of 2: read each and join them"):
        jp.LightCurve.from_fits(["a.fits", "b.fits"])
    with pytest.raises(ValueError, match="path must be one file, got a list of 2"):
        jp.LightCurve.from_csv(["a.csv", "b.csv"])
    with pytest.raises(ValueError, match="flux_column must be a column name such as 'PDCSAP_FLUX', got None"):
        jp.LightCurve.from_fits("a.fits", flux_column=None)
    with pytest.raises(ValueError, match=r"in_transit must hold one bool per point, shape \(10,\), got shape \(5,\)"):
        lc.normalized([(0.0, 0.02)], np.zeros(5, bool))
    with pytest.raises(ValueError, match=r"intervals must be \(start, end\) pairs"):
        lc.normalized((0.0, 0.02), np.zeros(10, bool))


def test_from_lightkurve_binned_and_stitched_exposure(tmp_path):
    """A lightkurve light curve binned to 29.4 min (TESS 2-min data binned to
    Kepler's cadence, to join them) keeps the 2-min TIMEDEL in its meta, and
    from_lightkurve modelled every 29.4-min bin over 2 minutes without a word:
    the exposure is now the bin size. A Kepler + TESS stitch carries one
    part's meta (TIMEDEL, mission) for all points: a warning says so."""
    import lightkurve as lk
    from pathlib import Path

    fits_path = Path(jp.__file__).parent / "data" / "kepler51" / "tess2019198215352-s0014-0000000027846348-0150-s_lc.fits"
    _lc_fits(tmp_path / "k.fits", n=200)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tess = lk.read(str(fits_path))[:3000]
        kep = lk.read(str(tmp_path / "k.fits"))
        binned = tess.bin(time_bin_size=0.0204335982)
        stitched = lk.LightCurveCollection([kep, tess]).stitch()
    assert binned.meta["TIMEDEL"] == pytest.approx(2.0 / 1440)
    got = jp.LightCurve.from_lightkurve(binned)
    assert got.exposure == pytest.approx(0.0204335982, rel=1e-9)
    assert jp.LightCurve.from_lightkurve(tess).exposure == pytest.approx(2.0 / 1440)  # unbinned: TIMEDEL
    assert jp.LightCurve.from_lightkurve(binned, exposure=0.02).exposure == 0.02  # given: taken as is
    with pytest.warns(UserWarning, match=r"time is in BKJD \(kepler\) but its meta names tess: one stitched"):
        jp.LightCurve.from_lightkurve(stitched)
    with pytest.warns(UserWarning, match="one stitched"):  # a given exposure: the quality bits are still one part's
        jp.LightCurve.from_lightkurve(stitched, exposure=2.0 / 1440)


def test_from_arrays_refuses_columns_of_other_shapes():
    """A scalar error, a 2D time or a quality column of another length gave
    numpy's IndexError or broadcast errors; now a ValueError with the shapes."""
    t = np.linspace(0.0, 1.0, 10)
    with pytest.raises(ValueError, match=r"arrays: time, flux, flux_err must be 1D of equal length .* flux_err \(\)"):
        jp.LightCurve.from_arrays(t, np.ones(10), 1e-3)
    with pytest.raises(ValueError, match=r"quality must be 1D of equal length .* quality \(3,\)"):
        jp.LightCurve.from_arrays(t, np.ones(10), np.full(10, 1e-3), quality=np.zeros(3))
    with pytest.raises(ValueError, match=r"time \(1, 10\)"):
        jp.LightCurve.from_arrays(t[None], np.ones((1, 10)), np.full((1, 10), 1e-3))
    assert len(jp.LightCurve.from_arrays(t, 1 + 1e-3 * np.sin(7 * t))) == 10  # no flux_err: estimated


def test_fits_time_zero_comes_from_the_header(tmp_path):
    """A TESS file read with mission='kepler' (its quality bits taken as
    Kepler's) was shifted by to_time_zero with Kepler's zero point: BTJD
    taken for BKJD, 0 d instead of +2167 d, without a word. The zero point is
    the file's BJDREFI + BJDREFF."""
    _lc_fits(tmp_path / "t.fits", mission="tess")
    lc = jp.LightCurve.from_fits(tmp_path / "t.fits", mission="kepler")
    assert lc.time_zero == 2457000.0
    np.testing.assert_allclose(lc.to_time_zero("bkjd").time, lc.time + 2167.0, rtol=0, atol=1e-9)


def test_report_line_counts_points_left_out_by_a_selection(tmp_path):
    """A window selected from a file said "4 of 50 points kept ...; dropped:
    2 flagged, 1 non-finite ..., 1 repeated" (46 points unaccounted for):
    the points a selection left out are counted too."""
    _lc_fits(tmp_path / "t.fits", mission="tess")
    lc = jp.LightCurve.from_fits(tmp_path / "t.fits")
    assert "more left out" not in lc.report_line()
    part = lc.select(np.arange(len(lc)) < 10)
    line = part.report_line()
    assert line.startswith("10 of 50 points kept") and f"; {len(lc) - 10} more left out by a selection" in line


def test_csv_errors_of_another_flux_column_warn(tmp_path):
    """A CSV with a relative flux, the raw PDCSAP flux and only its error
    column (time, flux, pdcsap_flux, pdcsap_flux_err) gave the relative flux
    errors in e-/s (chi^2 ~ 1e-10) without a word."""
    import warnings

    t = np.linspace(0.0, 1.0, 20)
    raw = 1e5 * (1 + 1e-3 * np.sin(9 * t))
    _write(tmp_path / "a.csv", "time,flux,pdcsap_flux,pdcsap_flux_err", (t, raw / 1e5, raw, np.full(20, 30.0)))
    with pytest.warns(UserWarning, match="column 'pdcsap_flux_err', which belongs to column 'pdcsap_flux', not to "
                                         "the flux column 'flux'"):
        jp.LightCurve.from_csv(tmp_path / "a.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lc = jp.LightCurve.from_csv(tmp_path / "a.csv", columns={"flux": "pdcsap_flux"})  # its own errors: quiet
        np.testing.assert_allclose(lc.flux_err, 30.0 / np.median(raw))


def test_a_current_zero_point_against_the_files_own_is_refused():
    """The REAL TESS sector-14 light curve of Kepler-51 (BTJD, from its
    header) given to_time_zero("bkjd", current="bkjd") was shifted by +0.0
    d and labelled BKJD: its BTJD times 1683-1710 sat beside Kepler's BKJD
    as if on one scale (d's transit 2167 d from where the label says), and
    concatenate took the label. A current that contradicts the light
    curve's own time_zero is now refused naming both; where the zero point
    is unknown, current still declares it, and agreeing is fine."""
    from pathlib import Path

    import jaxppo as jp

    fits = Path(jp.__file__).parent / "data" / "kepler51" / "tess2019198215352-s0014-0000000027846348-0150-s_lc.fits"
    tess = jp.LightCurve.from_fits(fits)
    assert tess.time_zero == 2457000.0
    with pytest.raises(ValueError, match=r"current = 'bkjd' \(BJD_TDB - 2454833.0 \(BKJD\)\) contradicts the light "
                                         r"curve's own zero point, BJD_TDB - 2457000.0 \(BTJD\)"):
        tess.to_time_zero("bkjd", current="bkjd")
    bk = tess.to_time_zero("bkjd", current="btjd")
    assert np.array_equal(bk.time, tess.time + 2167.0)
    with pytest.raises(ValueError, match="contradicts"):
        bk.to_time_zero("btjd", current="btjd")  # it counts from BKJD now
    csv = jp.LightCurve(np.array([1689.0, 1690.0]), np.ones(2), np.full(2, 1e-3))
    assert csv.to_time_zero("bkjd", current="bkjd").time_zero == 2454833.0
