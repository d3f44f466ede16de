"""``printapp preview``: a quick off-screen look at any mesh with pyvista (no path tracing)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def quick_view(path: Path, out: Path, width_px: int = 800, height_px: int = 600) -> int:
    """Render ``path`` shaded, from above at an angle, into ``out`` (PNG); returns the triangle count.

    pyvista draws off screen (OSMesa or EGL where there is no display); the image is
    written under a temporary name and renamed.
    """
    from printapp.mesh import read_mesh

    mesh = read_mesh(path)
    os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")
    import pyvista as pv
    import vtk

    pv.OFF_SCREEN = True
    # Without a display VTK warns that X is missing, then falls back to off-screen
    # rendering, which is what is wanted here.
    vtk.vtkObject.GlobalWarningDisplayOff()
    faces = np.column_stack([np.full(len(mesh.faces), 3), mesh.faces]).ravel()
    surface = pv.PolyData(np.asarray(mesh.vertices, dtype=np.float64), faces)
    plotter = pv.Plotter(off_screen=True, window_size=(width_px, height_px))
    plotter.set_background("white")
    plotter.add_mesh(surface, color="#d9d2c5", smooth_shading=False, specular=0.3)
    plotter.camera_position = "iso"
    plotter.camera.elevation = 10
    plotter.reset_camera()
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(
        dir=out.parent, prefix=f".{out.stem}.", suffix=".png", delete=False
    ) as tmp:
        staged = Path(tmp.name)
    try:
        plotter.screenshot(str(staged))
        plotter.close()
        staged.replace(out)
    finally:
        staged.unlink(missing_ok=True)
    return int(len(mesh.faces))
