"""lightcal: calibrate where a light sits and points relative to its camera."""

__version__ = "0.1.0"
