"""Open Image Denoise for previews, through ``pyoidn``; or, where it cannot run, no denoiser and why.

The denoiser is Intel's Open Image Denoise 2 (``RT`` filter, HDR input, guided by the albedo
and shading-normal images, "high" quality), on the CPU. It is deterministic: the same input
gives the same output, byte for byte (tests/test_convergence.py checks it). It never decides a
verdict alone: :mod:`render.convergence` measures the raw noise and the denoised preview's
own error against the halves it was not given.
"""

from __future__ import annotations

import os
from functools import lru_cache

import numpy as np

from render.convergence import Denoiser


@lru_cache(maxsize=1)
def open_image_denoise() -> tuple[Denoiser | None, str]:
    """The denoiser and its name, or ``(None, why not)``.

    ``PRINTAPP_DENOISER=off`` turns it off (previews then converge on samples alone).
    """
    if os.environ.get("PRINTAPP_DENOISER", "").lower() in ("off", "0", "none"):
        return None, "off (PRINTAPP_DENOISER=off)"
    try:
        import pyoidn
        from pyoidn import version as oidn_version
    except Exception as exc:  # an ImportError, or a missing shared library
        return None, f"unavailable (pyoidn does not load here: {exc})"
    name = getattr(oidn_version, "__version__", None) or getattr(oidn_version, "version", "")

    def denoise(colour: np.ndarray, albedo: np.ndarray, normal: np.ndarray) -> np.ndarray:
        out = pyoidn.denoise(
            np.ascontiguousarray(np.clip(colour, 0.0, None), dtype=np.float32),
            np.ascontiguousarray(np.clip(albedo, 0.0, 1.0), dtype=np.float32),
            np.ascontiguousarray(np.clip(normal, -1.0, 1.0), dtype=np.float32),
            hdr=True,
            quality="high",
        )
        return np.asarray(out, dtype=np.float64)

    try:  # a denoiser that cannot start (no CPU device) is no denoiser
        denoise(np.ones((8, 8, 3)), np.ones((8, 8, 3)), np.zeros((8, 8, 3)))
    except Exception as exc:
        return None, f"unavailable (Open Image Denoise failed to run: {exc})"
    return denoise, f"Open Image Denoise {name} (pyoidn; RT filter, HDR, albedo and normal guides)".replace(
        "  ", " "
    )
