"""The package version (its own module: no module imports the package root)."""

__version__ = "0.4.0"
