"""What the printer makes of the layers: the as-printed height field of a relief tile.

Sub-voxel model (documented, deliberately simple): a pixel of grey level g in a layer of
thickness t cures a slab of thickness t g / 255 on top of what is below it, i.e. cure
depth grows linearly with the exposure dose over the layer (Luongo et al. 2019,
"Microstructure control in 3D printing with digital light processing", use grey levels
to grow sub-voxel detail in the same way). A fully lit pixel cures the whole layer, a dark
one nothing. For a tile, whose every column is solid from the bed up, the printed height
of a pixel is therefore the sum over layers of t_k g_k / 255.
"""

from __future__ import annotations

import numpy as np

from slicing.layers import Slices


def printed_heights(slices: Slices) -> np.ndarray:
    """As-printed height (mm above the bed) of each pixel of the slices' window.

    Returns
    -------
    (rows, cols) float64 array, row 0 at the smallest Y, column 0 at the smallest X, for
    pixel centres at ((col0 + c + 1/2) px, (row0 + r + 1/2) py) in bed coordinates.
    """
    p = slices.profile
    heights = np.zeros((slices.rows, slices.cols))
    for k, cov in slices.coverages():
        thickness = p.initial_layer_height_mm if k == 0 else slices.layer_height_mm
        heights += thickness * slices.grey(cov) / 255.0
    return heights


def pixel_centres_mm(slices: Slices) -> tuple[np.ndarray, np.ndarray]:
    """Bed x and y (mm) of the window's pixel centres, as 1-D arrays along columns and rows."""
    p = slices.profile
    x = (slices.col0 + np.arange(slices.cols) + 0.5) * p.pitch_x_mm
    y = (slices.row0 + np.arange(slices.rows) + 0.5) * p.pitch_y_mm
    return x, y
