"""The scan config (TOML): [data] inputs, unknown keys, the template."""

import gzip

import numpy as np
import pytest

import jaxppo as jp
from jaxppo._config import load_config

BASE = """
[star]
law = "quadratic"
coefficients = [0.495, 0.154]

[[planet]]
name = "b"
period = 3.69611590
t0 = 134.501962
a = 10.60
inc = 87.687
radius = 0.01805
tilted = true

[[planet]]
name = "c"
period = 10.85408479
t0 = 138.608470
a = 22.764
inc = 89.967
radius = 0.02878

[data]
{data}

[scan]
alpha = [0.0, 360.0, 1.0]
"""


def _lc():
    return jp.simulate_kepler20(seed=2, noise=4e-4)


def _csv(path, header, cols):
    text = header + "\n" + "\n".join(",".join(f"{v:.12g}" for v in row) for row in zip(*cols)) + "\n"
    if path.name.endswith(".gz"):
        with gzip.open(path, "wt") as fh:
            fh.write(text)
    else:
        path.write_text(text)


def _cfg(tmp_path, data):
    p = tmp_path / "c.toml"
    p.write_text(BASE.format(data=data))
    return p


def test_data_columns_named_by_the_user(tmp_path):
    lc = _lc()
    _csv(tmp_path / "d.csv", "time,flux,error", (lc.time, lc.flux, lc.flux_err))
    cfg = load_config(_cfg(tmp_path, 'path = "d.csv"\ncolumns = {flux_err = "error"}'))
    np.testing.assert_allclose(cfg.lightcurve.flux_err, lc.flux_err, rtol=1e-11)
    with pytest.raises(ValueError, match=r"\[data\].*columns.flux_err = 'err_flux' is not a column"):
        load_config(_cfg(tmp_path, 'path = "d.csv"\ncolumns = {flux_err = "err_flux"}'))


def test_data_several_gzipped_quarters(tmp_path):
    lc = _lc()
    half = lc.time.size // 2
    for k, (sl, level) in enumerate(((slice(0, half), 1.5e5), (slice(half, None), 0.8e5))):
        _csv(tmp_path / f"q{k}.csv.gz", "time_bkjd,pdcsap_flux,pdcsap_flux_err",
             (lc.time[sl], lc.flux[sl] * level, lc.flux_err[sl] * level))
    cfg = load_config(_cfg(tmp_path, 'path = ["q0.csv.gz", "q1.csv.gz"]\nexposure = 0.0204336'))
    got = cfg.lightcurve
    assert len(got) == len(lc) and got.exposure == 0.0204336
    # each file divided by its own median: the levels are gone
    for sl in (slice(0, half), slice(half, None)):
        np.testing.assert_allclose(got.flux[sl] * np.median(lc.flux[sl]), lc.flux[sl], rtol=1e-10)
    with pytest.raises(ValueError, match=r"\[data\] file not found: .*q9.csv"):
        load_config(_cfg(tmp_path, 'path = ["q0.csv.gz", "q9.csv"]'))
    with pytest.raises(ValueError, match=r"\[data\] path must be"):
        load_config(_cfg(tmp_path, "path = []"))
