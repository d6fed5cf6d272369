"""Camera-design workbench: spectral scene -> optics -> sensor -> ISP."""
from workbench.allocator import tune_allocator

__version__ = "0.1.0"

tune_allocator()          # in every process that simulates: freed frame memory is reused (allocator.py)
