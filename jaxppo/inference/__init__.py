"""Inference workflows. Imports the model layer and the kernels only.

* ``_params``: the named free parameters and their coordinates;
* ``_model``: ``Model`` (theta -> System -> light curve, residuals,
  likelihood) and its jitted functions;
* ``_fit``: least-squares fits (optimistix) and their minimum check;
* ``_sample``: NUTS (numpyro) with physical priors;
* ``_diagnostics``: R-hat and effective sample sizes;
* ``_serialise``: results on disk (strict JSON);
* ``_posterior``: the transit posterior the marginalised obliquity scan
  draws from, and alpha sampled jointly with it;
* ``_importance``: the importance-sampling guard.
"""
