"""Texture synthesis kernels for printapp: sparse convolution noise, fBm, turbulence, veins, LIC.

Pure numerics on arrays (numba kernels); no file I/O, no printing. Scattered points
go through :func:`sparse_convolution`, :func:`fbm`, :func:`turbulence`,
:func:`unit_noise` and :func:`veins`; regular grids through the faster ``*_grid``
functions. On surfaces, :func:`sparse_convolution_framed`, :func:`fbm_framed` and
:func:`turbulence_framed` (:mod:`noise.framed`) stretch the noise along each point's
tangent frame (:func:`noise.frames.surface_frames`). Branching veins (:func:`vein_network`:
Musgrave's ridged multifractal over noise or Worley's :func:`cellular` edges,
:func:`domain_warp`) are in :mod:`noise.ridged`, with the noise tables fitting reads
(:mod:`noise.tables`) and the line filters that measure veins (:mod:`noise.line_filters`).
Also here, as the lowest room:
:class:`noise.heightfield.HeightField` (the type tiles are exchanged in), counter-based
hashing (:mod:`noise.hashing`), tangent frames (:mod:`noise.frames`), line integral
convolution (:mod:`noise.lic`, :mod:`noise.surface`) and spectra (:mod:`noise.spectra`).
"""

from noise.cellular import cellular
from noise.framed import fbm_framed, sparse_convolution_framed, turbulence_framed
from noise.ridged import domain_warp, vein_network
from noise.scn import (
    CELL_SEED_MODES,
    fbm,
    fbm_grid,
    octaves_for_pitch,
    sparse_convolution,
    sparse_convolution_grid,
    turbulence,
    turbulence_grid,
    unit_noise,
)
from noise.veins import veins, veins_grid

__all__ = [
    "CELL_SEED_MODES",
    "cellular",
    "domain_warp",
    "fbm",
    "fbm_framed",
    "fbm_grid",
    "octaves_for_pitch",
    "sparse_convolution",
    "sparse_convolution_framed",
    "sparse_convolution_grid",
    "turbulence",
    "turbulence_framed",
    "turbulence_grid",
    "unit_noise",
    "vein_network",
    "veins",
    "veins_grid",
]
