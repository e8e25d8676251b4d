"""transit_times / transit_epochs of a [[planet]] table: inline lists or a
CSV/ECSV file (columns epoch, tc, tc_err) relative to the config's folder."""

from pathlib import Path

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.obliquity._config import load_config

from test_config import BASE  # noqa: E402  (the same two-planet config)


def _write(tmp_path, planet_b_extra):
    jp.simulate_kepler20(seed=2, noise=4e-4).to_csv(tmp_path / "d.csv")
    text = BASE.format(data='path = "d.csv"').replace('name = "b"', 'name = "b"\n' + planet_b_extra, 1)
    p = tmp_path / "c.toml"
    p.write_text(text)
    return p


def test_inline_and_file_transit_times(tmp_path):
    t0, period = 134.501962, 3.69611590
    times = [t0 + 1 * period + 0.002, t0 + 40 * period - 0.001]
    inline = load_config(_write(tmp_path, f"transit_times = {times}\ntransit_epochs = [1, 40]"))
    b = inline.system.planets[0]
    assert b.transit_epochs == (1, 40) and np.array_equal(np.asarray(b.transit_times), times)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.csv").write_text("epoch,tc,tc_err\n" + "\n".join(
        f"{n},{tc!r},0.0007" for n, tc in zip((1, 40), times)) + "\n")
    from_file = load_config(_write(tmp_path, 'transit_times = "sub/b.csv"'))
    fb = from_file.system.planets[0]
    assert fb.transit_epochs == (1, 40) and np.array_equal(np.asarray(fb.transit_times), times)
    # the digest follows the times in the file, not only its name
    (tmp_path / "sub" / "b.csv").write_text("epoch,tc,tc_err\n1,%r,0.0007\n40,%r,0.0007\n" % (times[0] + 1e-4, times[1]))
    assert load_config(_write(tmp_path, 'transit_times = "sub/b.csv"')).digest != from_file.digest
    # ECSV by suffix
    from astropy.table import Table

    Table({"epoch": [1, 40], "tc": times, "tc_err": [7e-4, 7e-4]}).write(tmp_path / "b.ecsv", format="ascii.ecsv")
    eb = load_config(_write(tmp_path, 'transit_times = "b.ecsv"')).system.planets[0]
    assert np.array_equal(np.asarray(eb.transit_times), times)
    # a config without transit times keeps its digest (resumed scans survive)
    assert "transit_times" not in load_config(_write(tmp_path, "")).raw["planet"][0]


def test_file_transit_times_respect_units_and_whole_epochs(tmp_path):
    """An ECSV file states its units: a tc column in hours was read as days
    (refused as 3179 d off its ephemeris) and an epoch 1.6 was truncated to
    1 without a word; now the unit is converted, a unit of something else
    and a fractional epoch are refused naming the file."""
    import astropy.units as u
    from astropy.table import Table

    t0, period = 134.501962, 3.69611590
    times = np.array([t0 + 1 * period + 0.002, t0 + 40 * period - 0.001])
    Table({"epoch": [1, 40], "tc": times * 24.0 * u.h}).write(tmp_path / "h.ecsv", format="ascii.ecsv")
    hb = load_config(_write(tmp_path, 'transit_times = "h.ecsv"')).system.planets[0]
    np.testing.assert_allclose(np.asarray(hb.transit_times), times, rtol=0, atol=1e-9)
    Table({"epoch": [1, 40], "tc": times * u.m}).write(tmp_path / "m.ecsv", format="ascii.ecsv")
    with pytest.raises(ValueError, match=r"m.ecsv.*column tc is in m, not a unit of time"):
        load_config(_write(tmp_path, 'transit_times = "m.ecsv"'))
    (tmp_path / "f.csv").write_text(f"epoch,tc\n1.6,{float(times[0])!r}\n40,{float(times[1])!r}\n")
    with pytest.raises(ValueError, match=r"f.csv.*column epoch must hold whole epoch numbers, got 1.6"):
        load_config(_write(tmp_path, 'transit_times = "f.csv"'))


@pytest.mark.parametrize("extra, match", [
    ("transit_epochs = [1]", "transit_epochs needs transit_times"),
    ('transit_times = "nope.csv"', "transit_times file .*nope.csv' not found"),
    ('transit_times = [1.0, "2"]', "transit_times must be a non-empty list of mid-times"),
    ("transit_times = [138.2, 141.9]\ntransit_epochs = [1.5, 2]", "transit_epochs must be a list of integers"),
    ("transit_times = [140.5]\ntransit_epochs = [1]", r"\[\[planet\]\] #1: planet .b.: transit time 140.5 d of epoch 1"),
])
def test_bad_transit_time_keys(tmp_path, extra, match):
    with pytest.raises(ValueError, match=match):
        load_config(_write(tmp_path, extra))


def test_marginal_scan_keeps_transit_times_consistent():
    """The marginal scan samples at a t0 moved to the middle of the data
    (same orbit); a planet with transit times keeps its t0 and epochs (its
    t0 cancels; "b.tc[3]" keeps naming the same transit), the default free
    parameters leave out its t0, and draws of that t0 are refused."""
    from jaxppo.obliquity._marginal import centre_epochs, _check_samples, default_free

    b = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.5, radius=0.1, name="b",
                  transit_times=[0.01, 9.985, 20.02, 30.0, 40.03], transit_epochs=[0, 1, 2, 3, 4])
    c = jp.Planet(period=13.0, t0=-6.0, a=25.0, inc=89.6, radius=0.08, name="c")
    system = jp.System(jp.Star("quadratic", [0.4, 0.2]), [b, c])
    centred = centre_epochs(system, 31.0)
    cb, cc = centred.planets
    assert float(cb.t0) == 0.0 and cb.transit_epochs == (0, 1, 2, 3, 4) and float(cc.t0) == 33.0
    t = np.linspace(-2.0, 42.0, 4001)
    assert np.allclose(np.asarray(centred.flux(t)), np.asarray(system.flux(t)), rtol=0, atol=1e-12)
    assert "b.t0" not in default_free(system) and "c.t0" in default_free(system) and "b.period" in default_free(system)
    with pytest.raises(ValueError, match="planet 'b' has transit_times"):
        _check_samples(system, {"b.t0": np.zeros(3)})


def _with_ttv(tmp_path, section: str):
    p = _write(tmp_path, "")
    p.write_text(p.read_text() + "\n[ttv]\n" + section + "\n")
    return p


def test_ttv_section_is_read_and_checked(tmp_path):
    (tmp_path / "ref.csv").write_text("planet,epoch,tc,tc_err\nb,0,134.5,0.001\n")
    cfg = load_config(_with_ttv(tmp_path, 'planets = ["c"]\nfree = ["lc.jitter"]\nsearch = 0.05\ngrid = 21\n'
                                          'min_points = 5\nreference = "ref.csv"'))
    assert cfg.ttv == {"planets": ["c"], "free": ("lc.jitter",), "search": 0.05, "grid": 21, "min_points": 5,
                       "reference": [str(tmp_path / "ref.csv")]}
    # [ttv] is not part of the scan's digest (it changes no scan result)
    assert cfg.digest == load_config(_write(tmp_path, "")).digest
    for section, match in [('planets = ["x"]', "planets: no planet 'x'"), ("grid = 2", "grid must be an integer >= 3"),
                           ('free = ["b.nope"]', r"free: unknown parameter\(s\) \['b.nope'\]"),
                           ("search = -1.0", "search must be a positive half-width"),
                           ('reference = "none.csv"', "reference file .*none.csv' not found"),
                           ("speed = 1", r"unknown key\(s\) \['speed'\]")]:
        with pytest.raises(ValueError, match=r"\[ttv\] " + match):
            load_config(_with_ttv(tmp_path, section))



def test_transit_times_from_a_table_of_several_planets(tmp_path):
    """A transit_times file with a planet column (jaxppo ttv's
    transit_times.ecsv) gives each planet its own rows."""
    t0, period = 134.501962, 3.69611590
    (tmp_path / "tt.csv").write_text("planet,epoch,tc,tc_err\n"
                                     f"c,0,138.6,0.001\nb,1,{t0 + period + 0.002!r},0.001\nb,2,{t0 + 2 * period!r},0.001\n")
    b = load_config(_write(tmp_path, 'transit_times = "tt.csv"')).system.planets[0]
    assert b.transit_epochs == (1, 2) and np.allclose(np.asarray(b.transit_times), [t0 + period + 0.002, t0 + 2 * period])
    (tmp_path / "tt.csv").write_text("planet,epoch,tc,tc_err\nc,0,138.6,0.001\n")
    with pytest.raises(ValueError, match="has no rows of planet 'b'"):
        load_config(_write(tmp_path, 'transit_times = "tt.csv"'))


def test_ttv_section_refuses_what_the_measurement_would_refuse_later(tmp_path):
    for section, match in [('planets = ["b", "b"]', r"planets: \['b', 'b'\] names a planet twice"),
                           ('free = ["b.t0"]', r"free: \['b.t0'\] are measured by jaxppo ttv")]:
        with pytest.raises(ValueError, match=r"c.toml: \[ttv\] " + match):
            load_config(_with_ttv(tmp_path, section))
    # the t0 of a planet not measured may be free
    assert load_config(_with_ttv(tmp_path, 'planets = ["c"]\nfree = ["b.t0"]')).ttv["free"] == ("b.t0",)


def test_kepler51_scan_config_places_the_double_transit_by_measured_times(tmp_path, capsys):
    """The bundled Kepler-51 scan config lists every planet's measured
    times; they put the b + d double transit at BKJD 1513.81, which the
    bundled light curve leaves out: the scan says so by name."""
    from jaxppo.cli import main

    path = Path(jp.__file__).parent / "data" / "kepler51" / "kepler51_scan.toml"
    cfg = load_config(path)
    assert [len(pl.transit_epochs) for pl in cfg.system.planets] == [31, 11, 11]
    (event,) = jp.multi_transits(cfg.system, 150.0, 1600.0)
    assert event.planets == ("b", "d") and abs(event.mid - 1513.808) < 0.002
    assert main(["scan", str(path), "--out", str(tmp_path / "k51"), "--quiet"]) == 2
    assert "contain no usable multi-transit of planet 'd'" in capsys.readouterr().err
