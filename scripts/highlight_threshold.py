"""How a lobe's anisotropy shows on the screen: the predicted highlight of the preview's mirror spot.

The brushed tile's view (24 x 16 mm, camera at -60 deg azimuth and 40 deg elevation, 256 x 192,
the spot at the camera's mirror image, its half side 0.12 of the bounding radius), lobes of
roughness 0.03 and 0.1 and anisotropy 1 to 7, their long axis in the plane of incidence (120
deg), across it (30 deg) and between (75 deg). Prints the highlight's long axis on the screen
and its elongation (render.highlight).

    .venv/bin/python scripts/highlight_threshold.py
"""

import math

import numpy as np

from render.highlight import PinholeCamera, SlopeLobe, highlight_shape, predicted_highlight

centre = np.array([12.0, 8.0, 0.85])
radius = math.dist((0.0, 0.0, 0.0), (24.0, 16.0, 1.7)) / 2.0
distance = 1.1 * radius / math.sin(math.radians(15.0))
lamp = 2.0 * radius + distance / 2.0


def on(az: float, el: float, r: float) -> tuple[float, float, float]:
    direction = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    return tuple(centre + r * direction)


az, el = math.radians(-60.0), math.radians(40.0)
camera = PinholeCamera(on(az, el, distance), tuple(centre), 30.0, 256, 192)
spot = on(az + math.pi, el, lamp)
for alpha in (0.03, 0.1):
    for ratio in (1.0, 1.5, 2.0, 3.0, 7.0):
        row = []
        for lobe_az in (120.0, 30.0, 75.0):
            lobe = SlopeLobe(alpha, alpha / ratio, math.radians(lobe_az))
            image, mask = predicted_highlight(camera, spot, 0.12 * radius, lobe, 1.6, (0.0, 24.0, 0.0, 16.0))
            s = highlight_shape(image, mask)
            row.append(f"lobe {lobe_az:5.1f} deg: screen {s.angle_deg:5.1f} deg x{s.elongation:4.2f}")
        print(f"roughness {alpha} anisotropy {ratio}: " + " | ".join(row))
