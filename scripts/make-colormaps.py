"""Write printapp/data/colormaps.toml: the report's colour maps as 256 sRGB colours each.

The report draws its BRDF maps with Pillow alone (importing matplotlib cost a design run about
a second); the colours are matplotlib's, sampled here once. tests/test_report_figures.py checks
the file against matplotlib. Run: .venv/bin/python scripts/make-colormaps.py
"""

from pathlib import Path

import matplotlib
import numpy as np

NAMES = ("magma", "RdBu_r")

lines = [
    "# The report's colour maps (printapp.report_figures), 256 sRGB colours each as hex triplets,",
    "# sampled from matplotlib by scripts/make-colormaps.py (magma: CC0, by Nathaniel Smith and",
    "# Stefan van der Walt; RdBu: ColorBrewer, by Cynthia Brewer, Apache-2.0 style licence).",
]
for name in NAMES:
    rgb = np.round(matplotlib.colormaps[name](np.arange(256))[:, :3] * 255.0).astype(np.uint8)
    lines.append(f'{name} = "{rgb.tobytes().hex()}"')
out = Path(__file__).resolve().parent.parent / "printapp" / "data" / "colormaps.toml"
out.write_text("\n".join(lines) + "\n")
print(f"wrote {out}")
