"""The scan config (TOML): [data] inputs, unknown keys, the template."""

import gzip
from pathlib import Path

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.obliquity._config import load_config

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


def test_data_exposure_in_minutes_is_refused_by_name(tmp_path):
    """``exposure = 29.4`` (the cadence in minutes) ended in "internal error: MemoryError: Unable to allocate
    40.9 GiB"; now a clear error naming [data] exposure and its value."""
    lc = _lc()
    _csv(tmp_path / "d.csv", "time,flux,flux_err", (lc.time, lc.flux, lc.flux_err))
    step = float(np.median(np.diff(lc.time)))
    assert load_config(_cfg(tmp_path, f'path = "d.csv"\nexposure = {step!r}')).lightcurve.exposure == step
    with pytest.raises(ValueError, match=r"\[data\].*exposure must be a number of days no longer than the points' "
                                         r"spacing, got 29.4 d"):
        load_config(_cfg(tmp_path, 'path = "d.csv"\nexposure = 29.4'))


def test_data_several_gzipped_quarters(tmp_path):
    lc = _lc()
    half = lc.time.size // 2
    for k, (sl, level) in enumerate(((slice(0, half), 1.5e5), (slice(half, None), 0.8e5))):
        _csv(tmp_path / f"q{k}.csv.gz", "time_bkjd,pdcsap_flux,pdcsap_flux_err",
             (lc.time[sl], lc.flux[sl] * level, lc.flux_err[sl] * level))
    # 1-min points: a 1-min exposure (29.4 min, which this test gave them, is refused now)
    cfg = load_config(_cfg(tmp_path, 'path = ["q0.csv.gz", "q1.csv.gz"]\nexposure = 0.000694444'))
    got = cfg.lightcurve
    assert len(got) == len(lc) and got.exposure == 0.000694444
    # each file divided by its own median: the levels are gone
    for sl in (slice(0, half), slice(half, None)):
        np.testing.assert_allclose(got.flux[sl] * np.median(lc.flux[sl]), lc.flux[sl], rtol=1e-10)
    with pytest.raises(ValueError, match=r"\[data\] file not found: .*q9.csv"):
        load_config(_cfg(tmp_path, 'path = ["q0.csv.gz", "q9.csv"]'))
    with pytest.raises(ValueError, match=r"\[data\] path must be"):
        load_config(_cfg(tmp_path, "path = []"))


# ---- unknown keys ------------------------------------------------------------------

def _valid(tmp_path):
    lc = _lc()
    lc.to_csv(tmp_path / "d.csv")
    return BASE.format(data='path = "d.csv"')


@pytest.mark.parametrize(
    "edit, where, key, close",
    [
        (lambda t: t.replace("tilted = true", "tilded = true"), r"\[\[planet\]\] #1 \(b\)", "tilded", "tilted"),
        (lambda t: t.replace('path = "d.csv"', 'path = "d.csv"\nexposure_time = 0.02'), r"\[data\]", "exposure_time", "exposure"),
        (lambda t: t.replace("alpha = [0.0, 360.0, 1.0]", "alphas = [0.0, 360.0, 2.0]"), r"\[scan\]", "alphas", "alpha"),
        (lambda t: t + 'case = ["same"]\n', r"\[scan\]", "case", "cases"),
        (lambda t: t.replace("radius = 0.02878", "radius = 0.02878\nincl = 89.9"), r"\[\[planet\]\] #2 \(c\)", "incl", "inc"),
        (lambda t: t.replace("coefficients = [0.495, 0.154]", "coeffs = [0.495, 0.154]"), r"\[star\] \(law = 'quadratic'\)", "coeffs", "coefficients"),
        (lambda t: t.replace("[scan]", "[scans]"), r"top level \(sections\)", "scans", "scan"),
        (lambda t: t.replace('path = "d.csv"', 'path = "d.csv"\ncolumns = {fluxerr = "e"}'), r"\[data\] columns", "fluxerr", "flux_err"),
    ],
)
def test_unknown_keys_are_errors_naming_the_closest_key(tmp_path, edit, where, key, close):
    """Old code ran these with defaults: planet 1 tilted whatever `tilded`
    said, no exposure smearing, the default alpha grid, both cases."""
    p = tmp_path / "c.toml"
    p.write_text(edit(_valid(tmp_path)))
    with pytest.raises(ValueError, match=rf"{where}: unknown key '{key}'; did you mean '{close}'\?"):
        load_config(p)


def test_tilted_must_be_a_boolean(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text(_valid(tmp_path).replace("tilted = true", 'tilted = "false"'))
    with pytest.raises(ValueError, match="tilted must be true or false"):
        load_config(p)


def test_key_of_another_law_is_an_error(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text(_valid(tmp_path).replace('law = "quadratic"', 'law = "quadratic"\nlimb = "rescale"'))
    with pytest.raises(ValueError, match=r"\[star\] \(law = 'quadratic'\): unknown key 'limb'"):
        load_config(p)


def test_init_writes_a_template_that_loads_and_names_every_key(tmp_path, capsys):
    from jaxppo.obliquity import _config
    from jaxppo.cli import main

    path = tmp_path / "mine.toml"
    assert main(["init", str(path)]) == 0
    cfg = load_config(path)
    assert cfg.detrend == 2 and cfg.lightcurve.exposure == 0.0204335982 and cfg.alpha.size == 360
    text = path.read_text()
    keys = (_config.SCAN_KEYS + _config.DATA_KEYS + _config.PLANET_KEYS + _config.COLUMN_KEYS
            + _config.SYSTEM_KEYS + _config.MOON_KEYS)
    for key in keys:
        assert f"{key} =" in text or (key == "moon" and "[[planet.moon]]" in text), key
    assert main(["init", str(path)]) == 2  # never overwrites without --force
    assert "exists" in capsys.readouterr().err
    assert main(["init", str(path), "--force"]) == 0


def test_init_template_scans_what_the_default_config_scans(tmp_path):
    """Issue 24 item 3: the template of `jaxppo init` lacked the default's
    multi_transits line, so it scanned 9 events (the b + c + e triple of BKJD
    160.33 included, 125 points) instead of the default's 8 (111 points)."""
    from jaxppo.cli import main
    from jaxppo.obliquity._windows import windows_and_events

    path = tmp_path / "mine.toml"
    assert main(["init", str(path)]) == 0
    mine, default = load_config(path), load_config()
    assert mine.events == default.events and len(default.events) == 8
    for f in ("cases", "margin", "block", "detrend", "baseline", "clip", "marginalize", "fit_free"):
        assert getattr(mine, f) == getattr(default, f), f
    np.testing.assert_array_equal(mine.alpha, default.alpha)
    assert mine.raw["fit"] == default.raw["fit"]  # the marginalised scan's density prior too
    assert repr(mine.system) == repr(default.system)
    np.testing.assert_array_equal(mine.lightcurve.time, default.lightcurve.time)
    wm, wd = windows_and_events(mine)[0], windows_and_events(default)[0]
    assert [w.event.mid for w in wm] == [w.event.mid for w in wd] and len(wd) == 8
    assert sum(w.time.size for w in wm) == sum(w.time.size for w in wd) == 111
    for a, b in zip(wm, wd):
        np.testing.assert_array_equal(a.time, b.time)
        np.testing.assert_array_equal(a.flux, b.flux)
        np.testing.assert_array_equal(a.flux_err, b.flux_err)


def test_every_key_is_documented():
    from pathlib import Path

    from jaxppo.obliquity import _config

    doc = (Path(__file__).resolve().parents[2] / "docs" / "config.md").read_text()
    keys = set(_config.SCAN_KEYS + _config.DATA_KEYS + _config.PLANET_KEYS + _config.COLUMN_KEYS
               + _config.SYSTEM_KEYS + _config.MOON_KEYS + _config.FIT_KEYS)
    keys |= {k for ks in _config.STAR_KEYS.values() for k in ks}
    for key in sorted(keys):
        assert f"`{key}`" in doc, key


def test_bundled_configs_load():
    from jaxppo.model._phoenix import data_path

    for name in ("kepler20_real_llc.toml", "kepler20_buchhave2016_llc.toml", "kepler20_synthetic.toml"):
        load_config(data_path(name))


def test_every_bundled_file_has_provenance_and_licence():
    """jaxppo/data/README.md lists each bundled file with its source and licence."""
    from jaxppo.model._phoenix import data_path

    folder = data_path("")
    text = (folder / "README.md").read_text()
    rows = [ln for ln in text.splitlines() if ln.startswith("| `")]
    for f in sorted(p.name for p in folder.iterdir() if p.is_file()):
        row = next((r for r in rows if f"`{f}`" in r.split("|")[1]), None)
        assert row is not None, f
        cells = [c.strip() for c in row.split("|")[1:-1]]
        assert len(cells) == 5 and all(cells[:4]), (f, cells)  # file, what, source, licence (cite may be '-')


def test_quoted_numbers_and_optional_scan_section(tmp_path):
    """A quoted planet value ("0.01805") was silently converted; a config
    without [scan] (every key has a default) was refused."""
    from jaxppo.model._phoenix import data_path as jp_data

    text = Path(jp_data("kepler20_synthetic.toml")).read_text()
    data = str(Path(jp_data("kepler20_synthetic_bc.csv")))
    text = text.replace('path = "kepler20_synthetic_bc.csv"', f'path = "{data}"')
    p = tmp_path / "c.toml"
    p.write_text(text.replace("radius = 0.02878", 'radius = "0.02878"'))
    with pytest.raises(ValueError, match=r"radius must be a number, got '0.02878'"):
        load_config(p)
    head, _, _ = text.partition("[scan]")
    p.write_text(head)
    cfg = load_config(p)
    assert cfg.alpha.size == 360 and cfg.cases == ("same", "opposite")


def test_marginalize_and_fit_free_keys(tmp_path):
    """[scan] marginalize and [fit] free are read and checked; neither
    changes the plain scan's digest (its progress survives a new N)."""
    from jaxppo.model._phoenix import data_path as jp_data

    text = Path(jp_data("kepler20_synthetic.toml")).read_text()
    data = str(Path(jp_data("kepler20_synthetic_bc.csv")))
    text = text.replace('path = "kepler20_synthetic_bc.csv"', f'path = "{data}"')
    p = tmp_path / "c.toml"
    p.write_text(text)
    base = load_config(p)
    assert base.marginalize == 0 and base.fit_free is None
    p.write_text(text.replace("[scan]\n", "[scan]\nmarginalize = 32\n") + '\n[fit]\nfree = ["b.t0", "c.radius"]\n')
    cfg = load_config(p)
    assert cfg.marginalize == 32 and cfg.fit_free == ("b.t0", "c.radius") and cfg.digest == base.digest
    for bad, match in (("marginalize = -1", "marginalize must be"), ("marginalize = 2.5", "marginalize must be")):
        p.write_text(text.replace("[scan]\n", f"[scan]\n{bad}\n"))
        with pytest.raises(ValueError, match=match):
            load_config(p)
    p.write_text(text + '\n[fit]\nfree = ["b.tzero"]\n')
    with pytest.raises(ValueError, match=r"unknown parameter\(s\) \['b.tzero'\]"):
        load_config(p)
    p.write_text(text + '\n[fit]\nfrees = ["b.t0"]\n')
    with pytest.raises(ValueError, match="free"):
        load_config(p)


def test_planet_eccentricity_keys(tmp_path):
    """e and omega are optional planet keys (they were rejected as unknown, so
    an eccentric system could not be scanned from a config)."""
    p = tmp_path / "c.toml"
    text = _valid(tmp_path)
    p.write_text(text.replace('name = "b"', 'name = "b"\ne = 0.2\nomega = 40.0', 1))
    b = load_config(p).system.planets[0]
    assert float(b.e) == 0.2 and float(b.omega) == 40.0 and not b.circular
    p.write_text(text)
    assert load_config(p).system.planets[0].circular
    p.write_text(text.replace('name = "b"', 'name = "b"\ne = "0.2"', 1))
    with pytest.raises(ValueError, match="e must be a number"):
        load_config(p)
    p.write_text(text.replace('name = "b"', 'name = "b"\ne = 1.2', 1))
    with pytest.raises(ValueError, match=r"e \(eccentricity\) must be in \[0, 1\)"):
        load_config(p)


@pytest.mark.parametrize("key, bad", [
    ("detrend", 2.5), ("detrend", 6), ("detrend", "linear"), ("detrend", True),
    ("margin", -0.01), ("baseline", 0.01), ("clip", 1.5), ("clip", "off"), ("block", 0),
    ("multi_transits", "334.02"),
])
def test_one_validator_for_config_and_python(tmp_path, key, bad):
    """The same bad [scan] value is refused by the config file and by
    jaxppo.scan() with the same message (they used to apply different rules:
    ``int(detrend) != detrend`` against ``isinstance(detrend, int)``)."""
    import tomllib

    import jaxppo as jp
    from jaxppo.obliquity._config import config_from_arguments, config_from_dict, synthetic_config_path

    path = synthetic_config_path()
    raw = tomllib.loads(path.read_text())
    raw["scan"] = dict(raw.get("scan", {}), **{key: bad})
    with pytest.raises(ValueError) as from_file:
        config_from_dict(raw, path.parent, "cfg.toml")
    kw = dict(margin=0.05, detrend=2, baseline=0.3, clip=5.0, multi_transits=None, block=60)
    kw[key] = bad
    lc = jp.LightCurve(np.linspace(0.0, 1.0, 10), np.ones(10), np.full(10, 1e-4))
    with pytest.raises(ValueError) as from_python:
        config_from_arguments(jp.kepler20_system(), lc, None, ("same",), **kw)
    assert str(from_file.value) == f"cfg.toml: [scan] {from_python.value}"
    assert str(from_python.value).startswith(f"{key} must be") and repr(bad) in str(from_python.value)


MOON_CONFIG = """
[star]
law = "quadratic"
coefficients = [0.4, 0.25]

[[planet]]
name = "b"
period = 40.0
t0 = 0.0
a = 60.0
inc = 89.9
radius = 0.09
mass = 3e-4

[[planet.moon]]
name = "I"
period = 1.2
t0 = {moon_t0}
a = 0.35
inc = 88.0
radius = 0.04
mass_ratio = 0.05
lnode = 10.0

[data]
path = "moon.csv"

[fit]
free = ["b.I.t0"]
"""


def _moon_system(moon_t0=0.15):
    moon = jp.Moon(period=1.2, t0=moon_t0, a=0.35, inc=88.0, radius=0.04, mass_ratio=0.05, lnode=10.0, name="I")
    b = jp.Planet(period=40.0, t0=0.0, a=60.0, inc=89.9, radius=0.09, mass=3e-4, moons=[moon], name="b")
    return jp.System(jp.Star.quadratic(0.4, 0.25), [b])


def _moon_config(tmp_path, moon_t0=0.13):
    """A one-planet config with a moon, on data simulated with the moon at t0 = 0.15."""
    lc = jp.simulate(_moon_system(), np.arange(-0.3, 0.3, 4.0 / 1440.0), noise=2e-4, seed=3)
    _csv(tmp_path / "moon.csv", "time,flux,flux_err", (lc.time, lc.flux, lc.flux_err))
    p = tmp_path / "moon.toml"
    p.write_text(MOON_CONFIG.format(moon_t0=moon_t0))
    return p


def test_moon_config_builds_the_python_system_and_fits_from_the_cli(tmp_path, capsys):
    """Issue 25: [[planet.moon]] tables give the Moons of jp.Moon, a config
    may hold one planet, `jaxppo fit` frees [fit] free by default and finds
    the moon's phase; the scan and `jaxppo ttv` refuse the moon, saying so."""
    import jax

    from jaxppo.cli import main

    p = _moon_config(tmp_path)
    cfg = load_config(p)
    want = _moon_system(0.13)
    got_leaves, got_def = jax.tree_util.tree_flatten(cfg.system)
    want_leaves, want_def = jax.tree_util.tree_flatten(want)
    assert got_def == want_def
    for g, w in zip(got_leaves, want_leaves):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))
    assert cfg.fit_free == ("b.I.t0",)
    out = tmp_path / "fit.json"
    assert main(["fit", str(p), "--quiet", "--out", str(out)]) == 0
    res = jp.FitResult.load(out)
    assert tuple(res.names) == ("b.I.t0",) and abs(res.values[0] - 0.15) < 3 * res.errors[0] < 0.01
    text = p.read_text()
    alone = tmp_path / "alone.toml"  # the planet without its moon
    alone.write_text((text[:text.index("[[planet.moon]]")] + text[text.index("[data]"):]).replace("b.I.t0", "b.t0"))
    for argv, match in ((["scan", str(p), "--out", str(tmp_path / "s")], "obliquity scan does not model moons"),
                        (["fit", str(p), "--windows"], "windows (jaxppo scan; fit and sample --windows) does not "
                         "model moons"),
                        (["ttv", str(p), "--out", str(tmp_path / "t")], "does not model moons"),
                        (["scan", str(alone), "--out", str(tmp_path / "s")], "needs at least two planets")):
        assert main(argv) == 2, argv
        assert match in capsys.readouterr().err, argv


@pytest.mark.parametrize("edit, match", [
    (("mass_ratio = 0.05", "mass_rato = 0.05"), r"moon #1 \(I\): unknown key 'mass_rato'; did you mean 'mass_ratio'"),
    (("radius = 0.04\n", ""), r"moon #1 \(I\) is missing \['radius'\]"),
    (("a = 0.35", 'a = "0.35"'), r"moon #1 \(I\): a must be a number, got '0.35'"),
    (("a = 0.35", "a = -0.35"), r"moon #1 \(I\): moon 'I': a must be finite and > 0, got -0.35"),
    (("mass = 3e-4", "mass = true"), r"\[\[planet\]\] #1 \(b\): mass must be a number"),
    (("[fit]", "[system]\nepoch = 1.0\n\n[fit]"), r"\['epoch'\] apply to N-body orbits only"),
    (("[fit]", "[system]\norbit = 'nbody'\n\n[fit]"), r"\[system\]: unknown key 'orbit'; did you mean 'orbits'"),
    (("[fit]", "[system]\norbits = 'rebound'\n\n[fit]"), r"orbits must be \"kepler\" or \"nbody\", got 'rebound'"),
    (("[fit]", "[system]\norbits = 'nbody'\nepoch = 0.0\nstar_mass = 1.0\n\n[fit]"), "star_radius"),
    (("[fit]", "[system]\norbits = 'nbody'\nepoch = 0.0\nstar_mass = 1.0\nstar_radius = 1.0\n"
      "span = [0.0]\n\n[fit]"), r"span must be \[t_min, t_max\]"),
])
def test_system_and_moon_keys_are_checked(tmp_path, edit, match):
    """Bad [system] and [[planet.moon]] entries fail naming the key."""
    p = _moon_config(tmp_path)
    p.write_text(p.read_text().replace(*edit, 1))
    with pytest.raises(ValueError, match=match) as err:
        load_config(p)
    assert str(err.value).count("moon #1") <= 1 and str(err.value).count(str(p)) == 1  # the place named once


def test_docs_nbody_example_is_the_bundled_config_and_unnamed_moons_match_python(tmp_path):
    """docs/config.md's N-body example said it was the bundled
    kepler51_nbody.toml with other numbers (star_radius 0.881, omega 12);
    an unnamed [[planet.moon]] was "m1" in parameter names where jp.Moon
    without a name is "moon0"."""
    import re
    import tomllib

    root = Path(__file__).resolve().parents[2]
    doc = (root / "docs" / "config.md").read_text()
    block = re.search(r"An N-body config.*?```toml\n(.*?)```", doc, re.S).group(1)
    example = tomllib.loads(block)
    bundled = tomllib.loads((root / "jaxppo" / "data" / "kepler51" / "kepler51_nbody.toml").read_text())
    assert example["system"] == bundled["system"]
    assert example["planet"][0] == bundled["planet"][0]
    p = _moon_config(tmp_path)
    p.write_text(p.read_text().replace('name = "I"\n', "").replace('free = ["b.I.t0"]', 'free = ["b.moon0.t0"]'))
    cfg = load_config(p)
    assert cfg.system.planets[0].moons[0].name == "" and cfg.fit_free == ("b.moon0.t0",)


# ---- review of the config surface (2026-11-29) --------------------------------------

def _tab_config(tmp_path, table_text, star_extra=""):
    lc = _lc()
    lc.to_csv(tmp_path / "d.csv")
    (tmp_path / "ld.csv").write_text(table_text)
    text = BASE.format(data='path = "d.csv"').replace(
        'law = "quadratic"\ncoefficients = [0.495, 0.154]', f'law = "tabulated"\npath = "ld.csv"{star_extra}')
    p = tmp_path / "c.toml"
    p.write_text(text)
    return p


def test_a_star_files_content_is_part_of_the_digest(tmp_path):
    """The digest covered the star file's path only: after the file was
    edited a rerun reported the earlier results as this config's ("nothing
    recomputed"), with another limb darkening."""
    mu = np.linspace(0, 1, 11)
    p = _tab_config(tmp_path, "".join(f"{m},{1 - 0.6 * (1 - m)}\n" for m in mu))
    before = load_config(p).digest
    (tmp_path / "ld.csv").write_text("".join(f"{m},{1 - 0.3 * (1 - m)}\n" for m in mu))
    assert load_config(p).digest != before
    # an analytic star's digest does not involve any file
    q = tmp_path / "q.toml"
    q.write_text(BASE.format(data='path = "d.csv"'))
    assert load_config(q).digest == load_config(q).digest


def test_a_star_table_with_a_header_and_its_errors(tmp_path):
    """The documented header row (mu,intensity) failed with "could not
    convert string 'mu'"; errors named neither [star] nor the file."""
    mu = np.linspace(0, 1, 11)
    rows = "".join(f"{m} {1 - 0.6 * (1 - m)}\n" for m in mu)
    cfg = load_config(_tab_config(tmp_path, "mu,intensity\n" + rows))
    assert float(cfg.system.star.intensity(1.0)) > float(cfg.system.star.intensity(0.0))
    with pytest.raises(ValueError, match=r"\[star\] law = 'tabulated' \(path = 'ld.csv'\): .*ld.csv, line 3: .* not two numbers"):
        load_config(_tab_config(tmp_path, "mu,intensity\n0,0.4\nx,y\n"))
    cfg3 = load_config(_tab_config(tmp_path, "".join(f"{m},{1 - 0.6 * (1 - m)},0.01\n" for m in mu)))  # a third column
    assert float(cfg3.system.star.intensity(0.5)) == float(cfg.system.star.intensity(0.5))
    with pytest.raises(ValueError, match=r"line 2: '0.5,,0.7' is not two numbers"):
        load_config(_tab_config(tmp_path, "0,0.4\n0.5,,0.7\n1,1\n"))
    with pytest.raises(ValueError, match=r"\[star\] law = 'tabulated' \(path = 'ld.csv'\): .*mu"):
        load_config(_tab_config(tmp_path, "0.2,0.5\n0.6,0.8\n1,1\n"))
    assert load_config(_tab_config(tmp_path, "0.2,0.5\n0.6,0.8\n1,1\n", "\npad_ends = true")).digest
    with pytest.raises(ValueError, match=r"takes mu = \[...\] and intensity = \[...\] or path = 'table.csv', not both"):
        load_config(_tab_config(tmp_path, rows, "\nmu = [0, 1]\nintensity = [0.4, 1]"))
    p = _tab_config(tmp_path, rows)
    p.write_text(p.read_text().replace('law = "tabulated"', 'law = "phoenix"'))
    with pytest.raises(ValueError, match=r"\[star\] path = 'ld.csv' \(.*ld.csv\): "):
        load_config(p)


def test_alpha_applies_to_a_config_without_a_scan_section(tmp_path):
    """load_config(path, alpha=...) (the command line's --alpha) was
    silently ignored when the config had no [scan] section: the 1-deg
    default grid was scanned instead."""
    p = tmp_path / "c.toml"
    p.write_text(_valid(tmp_path).partition("[scan]")[0])
    assert load_config(p, alpha=[0, 360, 30]).alpha.size == 12
    assert load_config(p, alpha=[0, 360, 1]).digest == load_config(p).digest
    for bad in (5, [0, 360, None], "abc"):
        with pytest.raises(ValueError, match=r"^alpha must be"):
            load_config(p, alpha=bad)
    p.write_text(_valid(tmp_path) + "cases = 5\n")
    with pytest.raises(ValueError, match=r"\[scan\] cases = 5: cases must be 'all', a case or a list of cases"):
        load_config(p)


def test_names_and_free_parameters_that_fits_cannot_take(tmp_path):
    """A planet named "b.x" (a candidate's name, KOI-94.01, is one) failed
    in fit with "no planet named 'b'"; a repeated [fit] free name failed
    only when a fit ran."""
    p = tmp_path / "c.toml"
    p.write_text(_valid(tmp_path).replace('name = "b"', 'name = "b.x"'))
    cfg = load_config(p)  # a scan takes it
    with pytest.raises(ValueError, match=r"the planet name 'b.x' contains '.', .* \(e.g. 'b_x'\)"):
        jp.fit(cfg.system, cfg.lightcurve, free=["b.x.t0"])
    p.write_text(_valid(tmp_path) + '[fit]\nfree = ["b.t0", "b.t0"]\n')
    with pytest.raises(ValueError, match=r"\[fit\] free names b.t0 more than once"):
        load_config(p)


def test_unintegrated_long_cadence_and_quoted_exposure(tmp_path):
    """29.4-min points without [data] exposure ran an instantaneous model
    (chi^2_0 162.2 instead of 130.4 on the real data) without a word; a
    quoted exposure was converted silently."""
    t = np.arange(0.0, 2.0, 0.0204336)
    _csv(tmp_path / "d.csv", "time,flux,flux_err", [t, np.ones_like(t), np.full_like(t, 1e-4)])
    with pytest.warns(UserWarning, match=r"\[data\] exposure is not set.*29.4 min apart"):
        load_config(_cfg(tmp_path, 'path = "d.csv"'))
    with pytest.raises(ValueError, match=r"\[data\] exposure must be a number of days, got '0.0204'"):
        load_config(_cfg(tmp_path, 'path = "d.csv"\nexposure = "0.0204"'))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_config(_cfg(tmp_path, 'path = "d.csv"\nexposure = 0.0204'))
        assert load_config(_cfg(tmp_path, 'path = "d.csv"\nexposure = 0')).lightcurve.exposure is None  # said so


def test_error_columns_under_other_names_and_repeated_header(tmp_path):
    """An "error" column (the docs' own example name) was ignored and the
    errors estimated without a word; a repeated header name was read."""
    t = np.arange(0.0, 1.0, 0.001)
    _csv(tmp_path / "d.csv", "time,flux,error", [t, np.ones_like(t), np.full_like(t, 3e-4)])
    assert np.allclose(load_config(_cfg(tmp_path, 'path = "d.csv"')).lightcurve.flux_err, 3e-4)
    noisy = 1 + 3e-4 * np.random.default_rng(1).standard_normal(t.size)
    _csv(tmp_path / "d.csv", "time,flux,ferrs", [t, noisy, np.full_like(t, 3e-4)])
    with pytest.warns(UserWarning, match=r"column 'ferrs' is not used: if it holds the flux errors, set columns.flux_err"):
        load_config(_cfg(tmp_path, 'path = "d.csv"'))
    _csv(tmp_path / "d.csv", "time,flux,Flux", [t, np.ones_like(t), np.ones_like(t)])
    with pytest.raises(ValueError, match=r"header names column\(s\) \['flux'\] more than once"):
        load_config(_cfg(tmp_path, 'path = "d.csv"'))


def _kepler_fits(path, t):
    """A minimal Kepler long-cadence light-curve FITS file (TIMEDEL 29.4 min)."""
    from astropy.io import fits

    cols = [fits.Column(name=n, format="D", array=a) for n, a in
            (("TIME", t), ("PDCSAP_FLUX", np.full(t.size, 1e5)), ("PDCSAP_FLUX_ERR", np.full(t.size, 10.0)))]
    hdu = fits.BinTableHDU.from_columns(cols + [fits.Column(name="SAP_QUALITY", format="J", array=np.zeros(t.size))],
                                        name="LIGHTCURVE")
    hdu.header["TIMEDEL"], hdu.header["BJDREFI"], hdu.header["BJDREFF"] = 0.02043359821692, 2454833, 0.0
    prim = fits.PrimaryHDU()
    prim.header["TELESCOP"] = "Kepler"
    fits.HDUList([prim, hdu]).writeto(path)


def test_data_exposure_replacing_a_fits_files_own_warns(tmp_path):
    """[data] exposure = 2 min (a TESS config's) on one Kepler long-cadence
    FITS file replaced its 29.4-min TIMEDEL without a word (a list of files
    warned); the same length to rounding, or none given, stays quiet."""
    import warnings

    _kepler_fits(tmp_path / "k.fits", 160.0 + np.arange(100) * 0.0204336)
    with pytest.warns(UserWarning, match=r"\[data\] exposure = 0.00138889 d replaces the file's own exposure "
                                         r"\(TIMEDEL\) 0.0204336 d \(29.4 min\)"):
        cfg = load_config(_cfg(tmp_path, 'path = "k.fits"\nexposure = 0.00138889'))
    assert cfg.lightcurve.exposure == 0.00138889
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_config(_cfg(tmp_path, 'path = "k.fits"')).lightcurve.exposure == 0.02043359821692
        load_config(_cfg(tmp_path, 'path = "k.fits"\nexposure = 0.0204336'))
