"""Stellar activity (Mueller et al. 2021, Sects. 2.4 and 3.2): rotation
period from a generalised Lomb-Scargle periodogram, per-quarter
variability, the rotation-chunk brightness map (paper Fig. 3) and a
few-spot inversion of one chunk; rotating spotted stars (``Spots``, also
``Star.with_spots``) and the PPO-or-spot comparison of a scan's dips.

Imports point down only: this package uses jaxppo's model layer (System,
kepler20_system); nothing in the model layer imports it."""

from ._map import BrightnessMap as BrightnessMap
from ._map import brightness_map as brightness_map
from ._map import plot_brightness_map as plot_brightness_map
from ._map import plot_periodogram as plot_periodogram
from ._map import plot_spot_fit as plot_spot_fit
from ._spots import KEPLER20_SPOT_CONTRAST as KEPLER20_SPOT_CONTRAST
from ._spots import SpotFit as SpotFit
from ._spots import fit_spots as fit_spots
from ._spots import spot_flux as spot_flux
from ._report import activity_report as activity_report
from ._ppo_or_spot import plot_ppo_or_spot as plot_ppo_or_spot
from ._ppo_or_spot import ppo_or_spot as ppo_or_spot
from ..model._star import Spots as Spots
from ._rotation import PAPER_ROTATION_PERIOD as PAPER_ROTATION_PERIOD
from ._rotation import PreparedLightCurve as PreparedLightCurve
from ._rotation import RotationResult as RotationResult
from ._rotation import load_kepler20_quarters as load_kepler20_quarters
from ._rotation import prepare_light_curve as prepare_light_curve
from ._rotation import quarter_variability as quarter_variability
from ._rotation import read_quarters_csv as read_quarters_csv
from ._rotation import rotation_period as rotation_period
from ._rotation import transit_mask as transit_mask
# the public API: what the reference documents and tests/test_docstrings.py checks
__all__ = [
    "BrightnessMap",
    "brightness_map",
    "plot_brightness_map",
    "plot_periodogram",
    "plot_spot_fit",
    "KEPLER20_SPOT_CONTRAST",
    "SpotFit",
    "fit_spots",
    "spot_flux",
    "activity_report",
    "plot_ppo_or_spot",
    "ppo_or_spot",
    "Spots",
    "PAPER_ROTATION_PERIOD",
    "PreparedLightCurve",
    "RotationResult",
    "load_kepler20_quarters",
    "prepare_light_curve",
    "quarter_variability",
    "read_quarters_csv",
    "rotation_period",
    "transit_mask",
]
