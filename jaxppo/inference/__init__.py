"""Inference workflows: parameter coordinates and the model, least-squares
fits (optimistix), NUTS (numpyro), diagnostics, serialisation and the
transit posterior the marginalised obliquity scan draws from. Imports the
model layer and the kernels only."""
