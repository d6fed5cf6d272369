"""Camera-design workbench: spectral scene -> optics -> sensor -> ISP."""
__version__ = "0.1.0"
