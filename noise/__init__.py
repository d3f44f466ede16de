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

from noise.lazy import lazy_package

# Names resolve on first use, so that the light modules (heightfield, hashing) load without numba.
lazy_package(
    __name__,
    {
        "cellular": "noise.cellular",
        "fbm_framed": "noise.framed",
        "sparse_convolution_framed": "noise.framed",
        "turbulence_framed": "noise.framed",
        "domain_warp": "noise.ridged",
        "vein_network": "noise.ridged",
        "CELL_SEED_MODES": "noise.scn",
        "fbm": "noise.scn",
        "fbm_grid": "noise.scn",
        "octaves_for_pitch": "noise.scn",
        "sparse_convolution": "noise.scn",
        "sparse_convolution_grid": "noise.scn",
        "turbulence": "noise.scn",
        "turbulence_grid": "noise.scn",
        "unit_noise": "noise.scn",
        "veins": "noise.veins",
        "veins_grid": "noise.veins",
    },
)

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
