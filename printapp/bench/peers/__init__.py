"""The files that drive ``printapp bench``'s peer tools, shipped inside the package.

``blender_displace.py`` is the script Blender runs for ``bench mesh`` (it imports
Blender's ``bpy``: never import it here); ``sl1_flat.ini`` is the PrusaSlicer profile
of ``bench slice``. Found with :mod:`importlib.resources`, so that an installed wheel
has them as a source checkout does.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from importlib.resources import as_file, files
from pathlib import Path


def peer_file(name: str) -> AbstractContextManager[Path]:
    """A peer file as a path on disk, for as long as the ``with`` block lasts.

    Parameters
    ----------
    name : str
        File name in this folder, e.g. ``"sl1_flat.ini"``.

    Returns
    -------
    contextlib.AbstractContextManager of pathlib.Path
        Yields the file's path; a temporary copy where the package is not on disk (a zip).
    """
    return as_file(files(__name__) / name)
