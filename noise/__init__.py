"""Texture synthesis kernels for printapp: sparse convolution noise, fBm and turbulence.

Pure numerics on arrays (numba kernels); no file I/O, no printing. Scattered points
go through :func:`sparse_convolution`, :func:`fbm`, :func:`turbulence` and
:func:`marble`; regular grids through the faster ``*_grid`` functions.
"""

from noise.scn import (
    CELL_SEED_MODES,
    fbm,
    fbm_grid,
    marble,
    octaves_for_pitch,
    sparse_convolution,
    sparse_convolution_grid,
    turbulence,
    turbulence_grid,
)
from noise.veins import veins, veins_grid

__all__ = [
    "CELL_SEED_MODES",
    "fbm",
    "fbm_grid",
    "marble",
    "octaves_for_pitch",
    "sparse_convolution",
    "sparse_convolution_grid",
    "turbulence",
    "turbulence_grid",
    "veins",
    "veins_grid",
]
