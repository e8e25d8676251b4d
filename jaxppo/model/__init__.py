"""The model layer: the objects a user holds (Star, Planet, System,
LightCurve), the light-curve engines above the kernels of
``jaxppo.core`` (exact, planned "auto", raster), sweeps over [case, alpha,
time] and the bundled Kepler-20 system. Imports only ``jaxppo.core``."""
