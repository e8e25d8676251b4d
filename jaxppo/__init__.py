"""jaxppo: transits with planet-planet occultations, in JAX.

Layers (imports point down only):

* ``jaxppo.core``: pure array kernels (intensity profiles, circle geometry,
  exact occultation integrals, raster coverage);
* models: :class:`Star`, :class:`Planet`, :class:`System`,
  :func:`occultation_flux`;
* workflows: multi-transits, fits, sampling, the obliquity scan and the CLI.

Enable float64 for science work: ``jax.config.update("jax_enable_x64", True)``
(the library never flips it for you).
"""

from ._flux import occultation_flux as occultation_flux
from ._star import Spots as Spots
from ._star import Star as Star
from ._sweep import sweep as sweep
from ._system import MultiTransit as MultiTransit
from ._system import Planet as Planet
from ._system import System as System
from ._system import alpha_limits as alpha_limits
from ._system import multi_transits as multi_transits
from ._system import multi_transit_counts as multi_transit_counts
from ._system import hemisphere_cases as hemisphere_cases
from ._system import case_label as case_label

__version__ = "0.2.0"
from ._raster import RasterSettings as RasterSettings
from ._phoenix import band_intensity as band_intensity
from ._phoenix import claret_power2 as claret_power2
from ._phoenix import claret_quadratic as claret_quadratic
from ._phoenix import kepler20_star as kepler20_star
from ._phoenix import kepler_response as kepler_response
from ._phoenix import phoenix_star as phoenix_star
from ._phoenix import read_specint as read_specint
from ._phoenix import truncate_limb as truncate_limb
from ._lightcurve import LightCurve as LightCurve
from ._kepler20 import kepler20_system as kepler20_system
from ._kepler20 import simulate as simulate
from ._kepler20 import simulate_kepler20 as simulate_kepler20
from ._fit import FitResult as FitResult
from ._fit import fit as fit
from ._fit import parameter_names as parameter_names
from ._fit import kipping_q as kipping_q
from ._fit import kipping_u as kipping_u
from ._sample import SampleResult as SampleResult
from ._sample import sample as sample
from ._config import ScanConfig as ScanConfig
from ._config import load_config as load_config
from ._scan import ScanResult as ScanResult
from ._scan import ScanWindow as ScanWindow
from ._scan import scan as scan
from ._scan import scan_windows as scan_windows
from ._marginal import MarginalResult as MarginalResult
from ._marginal import marginal_scan as marginal_scan
from . import activity as activity
