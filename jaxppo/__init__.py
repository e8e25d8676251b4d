"""jaxppo: transits with planet-planet occultations, in JAX.

Layers (imports point down only; checked by import-linter in CI):

* ``jaxppo.core``: pure array kernels (intensity profiles, circle geometry,
  exact occultation integrals, raster coverage);
* ``jaxppo.model``: ``Star``, ``Planet``, ``System``,
  ``LightCurve``, ``occultation_flux``, ``sweep``,
  multi-transits;
* workflows: ``jaxppo.inference`` (fits, NUTS, the transit posterior),
  ``jaxppo.obliquity`` (the obliquity scan, marginalised or not),
  ``jaxppo.activity`` (rotation, spots, PPO or spot);
* ``jaxppo.cli`` on top.

Enable float64 for science work: ``jax.config.update("jax_enable_x64", True)``
(the library never flips it for you).
"""

from ._version import __version__ as __version__

from .model._cache import compilation_cache as compilation_cache
from .model._flux import occultation_flux as occultation_flux
from .model._star import Spots as Spots
from .model._star import Star as Star
from .model._sweep import sweep as sweep
from .model._transits import MultiTransit as MultiTransit
from .model._planet import Planet as Planet
from .model._system import System as System
from .model._moon import Moon as Moon
from .model._transits import alpha_limits as alpha_limits
from .model._transits import transit_times as transit_times
from .model._transits import multi_transits as multi_transits
from .model._transits import multi_transit_counts as multi_transit_counts
from .model._cases import hemisphere_cases as hemisphere_cases
from .model._cases import case_label as case_label

from .model._raster import RasterSettings as RasterSettings
from .model._phoenix import band_intensity as band_intensity
from .model._phoenix import claret_power2 as claret_power2
from .model._phoenix import claret_quadratic as claret_quadratic
from .model._phoenix import kepler20_star as kepler20_star
from .model._phoenix import kepler_response as kepler_response
from .model._phoenix import phoenix_star as phoenix_star
from .model._phoenix import read_specint as read_specint
from .model._phoenix import truncate_limb as truncate_limb
from .model._lightcurve import LightCurve as LightCurve
from .model._kepler20 import kepler20_system as kepler20_system
from .model._kepler20 import simulate as simulate
from .model._kepler20 import simulate_kepler20 as simulate_kepler20
from .inference._fit import FitResult as FitResult
from .inference._fit import fit as fit
from .inference._params import parameter_names as parameter_names
from .inference._params import kipping_q as kipping_q
from .inference._params import kipping_u as kipping_u
from .inference._sample import SampleResult as SampleResult
from .inference._sample import sample as sample
from .obliquity._config import ScanConfig as ScanConfig
from .obliquity._config import load_config as load_config
from .obliquity._scan import ScanResult as ScanResult
from .obliquity._windows import ScanWindow as ScanWindow
from .obliquity._scan import scan as scan
from .obliquity._windows import scan_windows as scan_windows
from .obliquity._marginal import MarginalResult as MarginalResult
from .obliquity._marginal import marginal_scan as marginal_scan
from .obliquity._joint import joint_scan as joint_scan
from . import activity as activity
from .inference._times import measure_transit_times as measure_transit_times
from .inference._times import linear_ephemeris as linear_ephemeris
# the public API: what the reference documents and tests/test_docstrings.py checks
__all__ = [
    "__version__",
    "compilation_cache",
    "occultation_flux",
    "Spots",
    "Star",
    "sweep",
    "MultiTransit",
    "Planet",
    "System",
    "Moon",
    "alpha_limits",
    "transit_times",
    "multi_transits",
    "multi_transit_counts",
    "hemisphere_cases",
    "case_label",
    "RasterSettings",
    "band_intensity",
    "claret_power2",
    "claret_quadratic",
    "kepler20_star",
    "kepler_response",
    "phoenix_star",
    "read_specint",
    "truncate_limb",
    "LightCurve",
    "kepler20_system",
    "simulate",
    "simulate_kepler20",
    "FitResult",
    "fit",
    "parameter_names",
    "kipping_q",
    "kipping_u",
    "SampleResult",
    "sample",
    "ScanConfig",
    "load_config",
    "ScanResult",
    "ScanWindow",
    "scan",
    "scan_windows",
    "MarginalResult",
    "marginal_scan",
    "joint_scan",
    "activity",
    "measure_transit_times",
    "linear_ephemeris",
]

from .model._programs import record_constants as _record_constants  # noqa: E402

_record_constants()  # the program store's reference (jaxppo.model._programs)
