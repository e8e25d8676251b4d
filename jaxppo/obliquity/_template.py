"""The commented config template of ``jaxppo init``: every key with its
unit and default, ready to run on the bundled real Kepler-20 data."""

from __future__ import annotations

import json
import tomllib

from ..model._phoenix import data_path
from ._config import default_config_path

__all__ = ["config_template"]


def config_template() -> str:
    """A commented config with every key (``jaxppo init``): the default scan
    of the real Kepler-20 long-cadence data, the data path absolute so that
    the file loads wherever it is written."""
    data = data_path("kepler20_kic6850504_llc_q1-q17_pdcsap.csv.gz")
    return f"""# jaxppo scan config; every key with units and defaults: docs/config.md.
# Run it:  jaxppo scan THIS_FILE.toml --out scan_out
# Unknown keys are errors (a typo never runs with a default).
# As written: Kepler-20 b + c (Mueller et al. 2021, Table 3 "This work") on
# the bundled real Kepler long-cadence data.

[star]
# law: quadratic | nonlinear | power2 | uniform | tabulated | phoenix
law = "nonlinear"
# coefficients of the law: quadratic u1, u2; nonlinear c1..c4; power2 c, alpha
# (here: fit to PHOENIX-ACES intensities, Teff 5500 K, log g 4.5)
coefficients = [1.0984732924, -1.74332475724, 2.46865245453, -0.995093958392]
# law = "tabulated": mu = [...] and intensity = [...], or path = "table.csv"
#   (columns mu, intensity); interpolation = "sqrt-poly" (default)
# law = "phoenix": path = "lte...PHOENIX-ACES-AGSS-COND-SPECINT-2011.fits";
#   limb = "rescale" (default)

# [system]              # optional; omitted: Keplerian orbits (the obliquity scan needs them)
# orbits = "nbody"      # "kepler" (default) | "nbody": planets moved by their mutual gravity
#                       # (pip install "jaxppo[nbody]"); fit and sample only
# epoch = 155.0         # [d] when the planets' elements osculate (N-body: required)
# star_mass = 0.985     # [M_sun] (N-body: required)
# star_radius = 0.881   # [R_sun] (N-body: required)
# dt = 1.0              # [d] integration step (default: shortest P (1 - e)^1.5 / 40)
# span = [155.0, 1600.0]  # [d] times the integration covers (default: the data's)

[[planet]]
name = "b"            # label, used in free-parameter names ("b.t0")
period = 3.69611590   # [d] orbital period
t0 = 134.501962       # [d] a mid-transit time, on the data's time scale (BKJD here)
a = 10.60             # [stellar radii] semi-major axis, > 1
inc = 87.687          # [deg] inclination, 0..180
radius = 0.01805      # planet-to-star radius ratio
e = 0.0               # eccentricity (optional, default 0: circular)
omega = 90.0          # [deg] argument of periastron (optional, default 90: periastron at transit)
# transit_times = [...] or "times.csv"; transit_epochs = [...]: measured mid-times [d] (TTVs, optional)
# lnode = 0.0         # [deg] longitude of the ascending node on the sky (optional, default 0)
# mass = 3e-5         # [M_sun] planet mass (N-body orbits; optional, default 0)
tilted = true         # this orbit is rotated by alpha (at most one planet; default: the first)
# [[planet.moon]]     # a moon of this planet (any number; fit and sample only)
# name = "I"          # label: its free parameters are "b.I.period", ...
# period = 1.5        # [d] of the moon's orbit about the planet
# t0 = 134.5          # [d] a time the moon passes in front of the planet
# a = 0.3             # [stellar radii] of the planet-moon orbit
# inc = 90.0          # [deg] of that orbit to the sky
# radius = 0.005      # moon-to-star radius ratio
# mass_ratio = 0.01   # moon / planet mass (default 0); lnode, e, omega as for a planet

[[planet]]
name = "c"
period = 10.85408479
t0 = 138.608470
a = 22.764
inc = 89.967
radius = 0.02878

[data]
# one file or a list (e.g. one per quarter): CSV, gzip CSV or Kepler FITS
path = "{data}"
# [d] integration time of each point: the model is averaged over it
# (Kepler long cadence 29.4 min = 0.0204335982 d; FITS files: from TIMEDEL;
# omit for instantaneous points)
exposure = 0.0204335982
# CSV column names, when they are not the usual ones (quarter: each quarter
# divided by its own median; no flux_err column: errors from the scatter)
# columns = {{time = "time_bkjd", flux = "pdcsap_flux", flux_err = "pdcsap_flux_err", quality = "sap_quality", quarter = "quarter"}}
# quality flags: a point is dropped when quality & bitmask != 0; "default"
# (the mission's recommended set: only cadences it calls unusable), "hard",
# "hardest" (every flag), "none" or an integer bitmask (docs/config.md lists the bits)
quality_bitmask = "default"
# mission = "kepler"   # "kepler" or "tess": the meaning of a CSV file's quality bits
#                      # (FITS files: from TELESCOP; a CSV without it: every flag drops the point)
""" + _template_scan_fit()


def _template_scan_fit() -> str:
    """[scan] and [fit] of the template, with the event selection and density
    prior read from the bundled default: "ready to run" must scan what
    `jaxppo scan` scans."""
    default = tomllib.loads(default_config_path().read_text())
    events, density = default["scan"]["multi_transits"], default["fit"]["stellar_density"]
    source = json.dumps(default["fit"]["stellar_density_source"])
    return f"""
[scan]
alpha = [0.0, 360.0, 1.0]      # [deg] start, stop, step; must span 360 deg, step dividing 360
cases = ["same", "opposite"]   # hemisphere cases (paper cases 1 and 4)
margin = 0.05                  # [d] out-of-transit data in the chi^2 on each side of an event
detrend = 2                    # order of each event's out-of-transit polynomial, or "none"
baseline = 0.3                 # [d] baseline fitted on each side of an event (> margin)
clip = 5.0                     # drop out-of-transit points beyond this many robust sigmas, or "none"
block = 60                     # alphas per progress record (resume granularity)
# [d] only the events with these mid-times (within 0.1 d; omit for all): the eight
# b + c double transits with no other planet on the disk. BKJD 160.33 is left out:
# planet e transits then too (a b + c + e triple), and e is not in this model.
multi_transits = {json.dumps(events)}
marginalize = 0                # draws of the scan marginalised over the transit posterior (0: off)

[fit]
# free = ["b.t0", "b.period", "b.a", "b.inc", "b.radius", "c.t0", "c.period", "c.a", "c.inc", "c.radius"]
#   parameters the marginalised scan samples with NUTS (default: these five of every planet;
#   the a/R* named here are tied to one stellar density by Kepler's third law), and
#   the default --free of jaxppo fit / sample (without it: every planet's t0 and radius)
# [g/cm^3] mean, sd: Gaussian prior on rho* (omitted: the density the planets'
# a/R* imply, 10 % wide); its source is copied to marginal.json
stellar_density = {json.dumps(density)}
stellar_density_source = {source}
"""
