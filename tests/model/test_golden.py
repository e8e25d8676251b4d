"""The whole model against real Blender (tests/golden, rendered by
blender/render_golden.py; the suite never needs bpy).

Blender moves the planets itself from the orbital elements in each scene file
(the paper's circular orbits, its R_y(alpha) tilt as an object rotation, the
hemisphere case); nothing in a golden comes from jaxppo. Each golden's header
carries its scene as one JSON line; here jp.System is rebuilt from it and
System.flux(t, alpha, case) is compared with Blender's light curve.

Tolerance: Blender's own error, measured on the uniform-star golden against
the exact area of the union of the two disks (1000 x 1000 pixels, 64
samples), times 3 (docs/blender.md: the Monte Carlo pixel-coverage noise of
the other scenes, with smaller planets, stays below that maximum). Slipped
conventions (the sign of alpha, the hemisphere case swapped, t0 one frame
late) move the planets and must fail the same comparison.
"""

import json
from pathlib import Path

import numpy as np
import pytest

import jaxppo as jp

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = ROOT / "tests" / "golden"
SCENES = ROOT / "blender" / "golden_scenes"
NAMES = sorted(p.stem for p in GOLDEN.glob("*.txt"))
PPO = [n for n in NAMES if n.startswith(("kepler20_", "kepler89_"))]


def read_golden(name):
    meta, rows = {}, []
    for line in (GOLDEN / f"{name}.txt").read_text().splitlines():
        if line.startswith("#"):
            key, _, val = line[1:].partition(":")
            try:
                meta[key.strip()] = json.loads(val)
            except json.JSONDecodeError:
                meta[key.strip()] = val.strip()
        elif line.strip():
            rows.append([float(v) for v in line.split()])
    return meta, np.array(rows)


def system_from_scene(scene, t0_shift=0.0):
    """jp.System from a golden's `# scene:` line; ``t0_shift`` [d] moves every
    planet's t0 (a slipped time convention)."""
    star = scene["star"]
    if "law" in star:
        st = jp.Star.from_law(star["law"], star["coefficients"])
    else:
        # Blender reads the table linearly between its nodes (as the paper did)
        st = jp.Star.tabulated(star["mu"], star["intensity"], interpolation="linear")
    planets = [jp.Planet(period=p["period"], t0=p["t0"] + t0_shift, a=p["a"], inc=p["inc"],
                         radius=p["radius"], name=p.get("name", "")) for p in scene["planets"]]
    if "spots" in scene:
        st = st.with_spots(**scene["spots"])
    return jp.System(st, planets, tilted=scene["tilted"])


def model(name, method="exact", alpha=None, case=None, t0_shift=0.0, spots=None):
    meta, data = read_golden(name)
    sc = dict(meta["scene"])
    if spots is not None:
        sc["spots"] = spots
    system = system_from_scene(sc, t0_shift)
    # a rotating spotted star takes the frames' times from System.flux
    return np.asarray(system.flux(data[:, 0], sc["alpha"] if alpha is None else alpha,
                                  sc["case"] if case is None else case, method=method))


def _blender_error():
    """Blender's largest error on the uniform-star golden. The reference is
    the area of the union of the two disks (jp.occultation_flux, exact, on a
    uniform star), at sky positions computed here from the elements, not by
    System: the tolerance must not move with the conventions under test."""
    meta, data = read_golden("uniform_overlap")
    sc = meta["scene"]
    assert sc["star"]["law"] == "uniform" and sc["alpha"] == 0.0 and sc["case"] == "same"
    t = data[:, 0, None]
    p = {k: np.array([pl[k] for pl in sc["planets"]]) for k in ("period", "t0", "a", "inc", "radius")}
    phi = 2 * np.pi * (t - p["t0"]) / p["period"]
    inc = np.deg2rad(p["inc"])
    x, y = p["a"] * np.sin(phi), p["a"] * np.cos(phi) * np.abs(np.cos(inc))
    r = np.where(p["a"] * np.cos(phi) * np.sin(inc) > 0, p["radius"], 0.0)
    union = np.asarray(jp.occultation_flux(jp.Star.uniform(), x, y, r, method="exact"))
    return float(np.max(np.abs(data[:, 1] - union)))


BLENDER_ERROR = _blender_error()
TOL = 3.0 * BLENDER_ERROR


def test_goldens_present_and_described():
    assert {"uniform_overlap", "quadratic_single", "kepler89_like_phoenix", "kepler89_de_prototype"} <= set(NAMES)
    assert len(PPO) >= 4
    for name in NAMES:
        meta, data = read_golden(name)
        assert meta["blender"].startswith("4.5") and meta["resolution"] == 1000 and meta["samples"] == 64
        assert meta["render_seconds"] > 0 and meta["frames"] == len(data)
        sc = meta["scene"]
        assert set(sc) - {"spots"} == {"star", "planets", "tilted", "alpha", "case"}
        assert all({"period", "t0", "a", "inc", "radius"} <= set(p) for p in sc["planets"])
        # the golden was rendered from the committed scene file
        spec = json.loads((SCENES / f"{name}.json").read_text())
        assert {k: spec[k] for k in sc} == sc, name
        np.testing.assert_allclose(data[:, 0], spec["times"], rtol=0, atol=1e-9)


def test_goldens_cover_the_geometries():
    scenes = {n: read_golden(n)[0]["scene"] for n in NAMES}
    ppo = [scenes[n] for n in PPO]
    assert {s["case"] for s in ppo} == {"same", "opposite"}
    assert any(s["alpha"] % 360 < 180 for s in ppo) and any(s["alpha"] % 360 > 180 for s in ppo)
    assert any(90 < s["alpha"] % 360 < 270 for s in ppo)  # a retrograde geometry
    assert "mu" in scenes["kepler89_like_phoenix"]["star"]
    assert len(scenes["quadratic_single"]["planets"]) == 1


def test_blender_error_is_small_and_measured():
    assert 1e-8 < BLENDER_ERROR < 5e-6


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("method", ["exact", "auto"])
def test_jaxppo_matches_blender(name, method):
    # NOTE kepler20_retro_same_inc_mirrored has inclinations > 90 deg (i -> 180 - i
    # of kepler20_retro_same). With the hemisphere cases defined from |b|
    # (|cos i| in y) it equals kepler20_retro_same; it fails while System still
    # uses the signed cos(i), and passes once that convention change is merged.
    meta, data = read_golden(name)
    if "spots" in meta["scene"] and method == "exact":
        with pytest.raises(ValueError, match="radially symmetric"):
            model(name, method)
        return
    dev = np.max(np.abs(model(name, method) - data[:, 1]))
    assert dev < TOL, (name, method, dev, TOL)


def test_mirrored_inclinations_render_the_same():
    # Blender against Blender: i -> 180 - i changes nothing in the rendered scene
    _, a = read_golden("kepler20_retro_same")
    _, b = read_golden("kepler20_retro_same_inc_mirrored")
    assert np.max(np.abs(a[:, 1] - b[:, 1])) < TOL


def _slips(name):
    meta, data = read_golden(name)
    sc = meta["scene"]
    frame = float(np.median(np.diff(data[:, 0])))
    out = {"t0 one frame late": model(name, t0_shift=frame)}
    if len(sc["planets"]) > 1:
        out["alpha sign"] = model(name, alpha=-sc["alpha"] if sc["alpha"] else 180.0)
        out["case swapped"] = model(name, case="opposite" if sc["case"] == "same" else "same")
    return data, out


@pytest.mark.parametrize("name", sorted(set(PPO) - {"kepler20_retro_same_inc_mirrored"}) + ["quadratic_single"])
def test_convention_slips_fail(name):
    data, slips = _slips(name)
    assert len(slips) == (1 if name == "quadratic_single" else 3)
    for what, slipped in slips.items():
        dev = np.max(np.abs(slipped - data[:, 1]))
        # the comparison of test_jaxppo_matches_blender must fail, clearly
        assert dev > 3 * TOL, (name, what, dev, TOL)


def test_spotted_star_slips_fail():
    """spot_crossing: the spot geometry slipped (obliquity sign, the axis
    inclination mirrored, the longitudes mirrored, the rotation phase 0.02 d
    late) must fail the comparison by more than 3 x TOL."""
    meta, data = read_golden("spot_crossing")
    sp = meta["scene"]["spots"]
    assert len(sp["lat"]) == 2 and sp["inc"] != 90 and sp["obliquity"] != 0
    slips = {
        "obliquity sign": dict(sp, obliquity=-sp["obliquity"]),
        "inclination mirrored": dict(sp, inc=180.0 - sp["inc"]),
        "longitudes mirrored": dict(sp, lon=[-v for v in sp["lon"]]),
        "rotation 0.02 d late": dict(sp, t_ref=sp["t_ref"] + 0.02),
    }
    for what, kw in slips.items():
        dev = np.max(np.abs(model("spot_crossing", "auto", spots=kw) - data[:, 1]))
        assert dev > 3 * TOL, (what, dev, TOL)
