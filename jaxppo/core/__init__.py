"""Pure array kernels: one frame, plain arrays in and out; no model objects."""
