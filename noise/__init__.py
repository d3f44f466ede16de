"""Texture synthesis kernels for printapp: sparse convolution noise, fBm and turbulence.

Pure numerics on arrays (numba kernels); no file I/O, no printing.
"""

from noise.scn import CELL_SEED_MODES, fbm, octaves_for_pitch, sparse_convolution, turbulence

__all__ = ["CELL_SEED_MODES", "fbm", "octaves_for_pitch", "sparse_convolution", "turbulence"]
