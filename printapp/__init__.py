"""printapp: appearance printing, from a design file to a verified, printable model.

The application room: command line, design schema, pipeline, mesh building, I/O and
benchmarks. The numerics live in the packages ``noise``, ``slicing`` and ``render``,
which never import this one.
"""

import os as _os

__version__ = "0.1.0"

# numba caches compiled kernels beside their modules; an installed package may not be
# writable there, so the cache moves to the user's cache folder (unless set already).
if "NUMBA_CACHE_DIR" not in _os.environ:
    _here = _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__)))
    if not _os.access(_os.path.join(_here, "noise"), _os.W_OK):
        _base = _os.environ.get("XDG_CACHE_HOME") or _os.path.join(_os.path.expanduser("~"), ".cache")
        _os.environ["NUMBA_CACHE_DIR"] = _os.path.join(_base, "printapp", "numba")
