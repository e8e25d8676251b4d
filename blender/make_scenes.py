"""Write the scene files of the Blender goldens (blender/golden_scenes/*.json).

Plain Python, no jaxppo: a scene is the star's law or (mu, I) table, the
planets' orbital elements, the tilted planet, alpha, the hemisphere case, the
times and the render settings. blender/render_golden.py moves the planets
from these elements inside Blender.

    python3 blender/make_scenes.py [blender/golden_scenes]
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

RESOLUTION = 1000
SAMPLES = 64

# Kepler-20 b and c, Mueller et al. (2021) Table 3 "This work" (T0 in BKJD)
K20_B = {"name": "b", "period": 3.6961159, "t0": 134.501962, "a": 10.60, "inc": 87.687, "radius": 0.01805}
K20_C = {"name": "c", "period": 10.85408479, "t0": 138.60847, "a": 22.764, "inc": 89.967, "radius": 0.02878}
# Kepler-20's star: non-linear law fitted to PHOENIX-ACES intensities, Teff 5500 K, log g 4.5,
# Kepler band (Espinoza & Jordan 2015, row P100), as jaxppo's kepler20_star
K20_STAR = {"law": "nonlinear", "coefficients": [1.0984732924, -1.74332475724, 2.46865245453, -0.995093958392]}


def frange(start: float, step: float, n: int) -> list[float]:
    return [round(start + k * step, 10) for k in range(n)]


def centred(mid: float, half: float, n: int) -> list[float]:
    return [round(mid - half + 2.0 * half * k / (n - 1), 10) for k in range(n)]


def phoenix_like_table() -> tuple[list[float], list[float]]:
    """78 mu points (uniform in the angle, as PHOENIX SPECINT files are dense
    toward the limb) of the power-2 law fitted to PHOENIX-COND intensities,
    Teff 5700 K, log g 4.5, Kepler band (Claret & Southworth 2023, table1, M1:
    g = 0.711031, h = 0.760998): a PHOENIX-like table with its steep limb."""
    g, h = 0.711031, 0.760998
    mu = sorted({0.0, 1.0} | {round(math.cos(x * math.pi / 2 / 77), 12) for x in range(1, 77)})
    return mu, [1.0 - g * (1.0 - m ** h) for m in mu]


def scenes() -> list[dict]:
    out = []

    def add(name, description, star, planets, tilted, alpha, case, times, source=""):
        out.append({"name": name, "description": description, "source": source,
                    "resolution": RESOLUTION, "samples": SAMPLES, "seed": 0,
                    "star": star, "planets": planets, "tilted": tilted, "alpha": alpha, "case": case,
                    "times": times})

    # 1. uniform star, two overlapping planets: the exact answer is the area of the
    #    union, so this golden measures Blender's own error
    add("uniform_overlap", "uniform star; planets b (p = 0.1) and c (p = 0.07) overlap each other on the disk",
        {"law": "uniform", "coefficients": []},
        [{"name": "b", "period": 3.0, "t0": 0.0, "a": 8.0, "inc": 88.0, "radius": 0.1},
         {"name": "c", "period": 7.0, "t0": 0.004, "a": 14.0, "inc": 89.2, "radius": 0.07}],
        0, 0.0, "same", centred(0.0, 0.075, 61))
    # 2. a single transit, quadratic limb darkening
    add("quadratic_single", "quadratic limb darkening u1 = 0.4, u2 = 0.26; single transit p = 0.1, b = 0.42",
        {"law": "quadratic", "coefficients": [0.4, 0.26]},
        [{"name": "b", "period": 3.0, "t0": 0.0, "a": 8.0, "inc": 87.0, "radius": 0.1}],
        0, 0.0, "same", centred(0.0, 0.08, 61))
    # 3.-6. Kepler-20 b (tilted) + c, planet-planet occultations in both cases, tilts
    #    on both sides of 180 deg, two retrograde; 30 s frames over +-15 min around the PPO
    half, n = 15.0 / 1440.0, 61
    for name, mid, alpha, case, what in (
        ("kepler20_ppo_same", 844.1556, 90.0, "same", "double transit at BKJD 844.13, alpha = 90 deg (b crosses c's track at right angles)"),
        ("kepler20_ppo_opposite", 844.1570, 90.0, "opposite", "double transit at BKJD 844.13, alpha = 90 deg"),
        ("kepler20_retro_opposite", 1017.8427, 144.0, "opposite", "double transit at BKJD 1017.82, alpha = 144 deg: retrograde (b moves toward -x)"),
        ("kepler20_retro_same", 1354.2308, 248.0, "same", "double transit at BKJD 1354.26, alpha = 248 deg: retrograde, tilt beyond 180 deg"),
    ):
        add(name, f"Kepler-20 b + c (paper Table 3), PHOENIX-based non-linear star (P100), case {case}, {what}; PPO of b over c",
            K20_STAR, [dict(K20_B), dict(K20_C)], 0, alpha, case, centred(mid, half, n),
            "Mueller et al. (2021) Table 3; Espinoza & Jordan (2015) P100 coefficients")
    # 7. the same retrograde scene with both inclinations mirrored, i -> 180 - i:
    #    with the hemisphere cases defined from |b| this must change nothing
    add("kepler20_retro_same_inc_mirrored",
        "kepler20_retro_same with i -> 180 - i for both planets (b 92.313, c 90.033 deg): the cases are defined from |b|, so the light curve is the same",
        K20_STAR, [dict(K20_B, inc=180.0 - K20_B["inc"]), dict(K20_C, inc=180.0 - K20_C["inc"])], 0, 248.0, "same",
        centred(1354.2308, half, n), "Mueller et al. (2021) Table 3, inclinations mirrored")
    # 8. large planets with a PPO on a tabulated PHOENIX-like profile (linear between nodes)
    mu, inten = phoenix_like_table()
    add("kepler89_like_phoenix",
        "large planets d (p = 0.055) and e (p = 0.068) with a PPO near mid-transit, alpha = -1.13 deg; tabulated PHOENIX-like profile (78 mu points, power-2 fit to PHOENIX-COND 5700 K, log g 4.5, Kepler), linear between nodes",
        {"mu": mu, "intensity": inten},
        [{"name": "d", "period": 22.34, "t0": 0.0, "a": 31.0, "inc": 89.5, "radius": 0.055},
         {"name": "e", "period": 54.32, "t0": 0.01, "a": 56.0, "inc": 89.75, "radius": 0.068}],
        0, -1.13, "same", centred(0.0, 0.2, 81), "Claret & Southworth (2023) table1 (M1)")
    # 9. the paper's Appendix B prototype: Kepler-89 d (tilted) + e
    out.extend(kepler89_prototype())
    # 10. a planet crossing a spot on a rotating, inclined, tilted star
    out.append(spot_crossing())
    return out


def spot_on_sky(x: float, y: float, inc: float, obliquity: float) -> tuple[float, float]:
    """(lat, lon) [deg] of the spot whose centre is at sky (x, y) (front
    hemisphere) at rotational phase 0: undo the sky rotation by the obliquity,
    then read latitude off the axis (0, sin i, cos i) and the longitude off
    the meridian facing the observer (0, -cos i, sin i) and +x."""
    z = math.sqrt(1.0 - x * x - y * y)
    ps, i = math.radians(obliquity), math.radians(inc)
    x0, y0 = x * math.cos(ps) - y * math.sin(ps), x * math.sin(ps) + y * math.cos(ps)
    lat = math.asin(y0 * math.sin(i) + z * math.cos(i))
    dl = math.atan2(x0, -y0 * math.cos(i) + z * math.sin(i))
    return round(math.degrees(lat), 8), round(-math.degrees(dl), 8)


def spot_crossing() -> dict:
    """One planet (p = 0.08, b = 0.3) crossing a dark spot (radius 10 deg,
    contrast 0.7, smooth 2-deg edge) on a quadratic star rotating in 5 d with
    its axis inclined to 70 deg and tilted by 20 deg on the sky; at
    mid-transit the spot's centre is at sky (-0.05, 0.3), and it moves by
    about 0.15 R* during the transit. A second spot on the other side rotates
    in over the limb (the rotational modulation)."""
    inc, obl = 70.0, 20.0
    lat1, lon1 = spot_on_sky(-0.05, 0.3, inc, obl)
    lat2, lon2 = spot_on_sky(-0.93, -0.2, inc, obl)
    spots = {"lat": [lat1, lat2], "lon": [lon1, lon2], "radius": [10.0, 6.0], "contrast": [0.7, 0.5],
             "period": 5.0, "inc": inc, "t_ref": 0.0, "obliquity": obl, "edge": 2.0}
    return {"name": "spot_crossing",
            "description": "quadratic star (0.4, 0.26) with two rotating spots (P 5 d, axis inclination 70 deg, sky obliquity 20 deg); one planet p = 0.08, b = 0.3 crosses the 10-deg spot (contrast 0.7)",
            "source": "", "resolution": RESOLUTION, "samples": SAMPLES, "seed": 0,
            "star": {"law": "quadratic", "coefficients": [0.4, 0.26]},
            "planets": [{"name": "b", "period": 3.0, "t0": 0.0, "a": 8.0, "inc": round(math.degrees(math.acos(0.3 / 8.0)), 10), "radius": 0.08}],
            "tilted": 0, "alpha": 0.0, "case": "same", "spots": spots,
            "times": centred(0.0, 0.065, 27)}


def kepler89_prototype() -> list[dict]:
    """The prototype PPO (paper Appendix B; Hirano et al. 2012; Masuda 2013):
    Kepler-89 (KOI-94) d, tilted, and e.

    Sources (this offline machine holds no copy of Masuda 2013 Tables 3-4,
    which the paper used): inclinations 89.871 and 89.76 deg (Masuda 2013, as
    tabulated for Kepler-89 d and e on Wikipedia); planet radii 11.27 and
    6.56 R_earth, stellar radius 1.52 R_sun, periods 22.3 and 54.3 d (Weiss
    et al. 2013, ApJ 768, 14); semi-major axes 0.165 and 0.298 au (as tabulated
    with those values), so a/R* = a [au] * 215.032 / 1.52 and
    p = R_p [R_earth] / 109.076 / 1.52; quadratic limb darkening u1 = 0.4639,
    u2 = 0.1962 (Claret 2018, PHOENIX-COND, Kepler band, Teff 6100 K,
    log g 4.0, next to Kepler-89's 6116 K, 4.12). The mid-times sit at the
    double transit of BJD 2455211.5 (BKJD 378.5, Hirano et al. 2012), e's
    0.04 d before d's, and alpha = -2.5 deg is the small mutual angle that
    then makes d pass over e (with these rounded a/R*, |b_d - b_e| = 0.124
    exceeds p_d + p_e = 0.108, so the paper's -1.13 deg leaves a gap)."""
    rs, re_rs, au_rs = 1.52, 1.0 / 109.076, 215.032
    d = {"name": "d", "period": 22.343, "t0": 378.5, "a": round(0.165 * au_rs / rs, 4), "inc": 89.871,
         "radius": round(11.27 * re_rs / rs, 5)}
    e = {"name": "e", "period": 54.320, "t0": 378.46, "a": round(0.298 * au_rs / rs, 4), "inc": 89.76,
         "radius": round(6.56 * re_rs / rs, 5)}
    return [{"name": "kepler89_de_prototype",
             "description": "Kepler-89 d (tilted) + e, the prototype planet-planet eclipse (paper Appendix B), alpha = -2.5 deg, case same; quadratic star (Claret 2018 PHOENIX-COND, Kepler, 6100 K, log g 4.0)",
             "source": "Masuda (2013) inclinations; Weiss et al. (2013) radii, stellar radius, periods, semi-major axes; Claret (2018) limb darkening; Hirano et al. (2012) epoch of the double transit",
             "resolution": RESOLUTION, "samples": SAMPLES, "seed": 0,
             "star": {"law": "quadratic", "coefficients": [0.4639, 0.1962]},
             "planets": [d, e], "tilted": 0, "alpha": -2.5, "case": "same",
             "times": centred(378.625, 0.06, 81)}]


def main(folder: str) -> None:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for sc in scenes():
        path = folder / f"{sc['name']}.json"
        path.write_text(json.dumps(sc, indent=1) + "\n")
        print(f"wrote {path}: {len(sc['times'])} frames")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else str(Path(__file__).resolve().parent / "golden_scenes"))
