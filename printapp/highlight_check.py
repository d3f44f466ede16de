"""The anisotropic highlight, shown and verified: the spot at the camera's mirror, the streak's moments.

A brushed relief's highlight is a streak across its grooves (:mod:`render.highlight`).
Under the default studio light the small spot stands 90 degrees of azimuth away from
the camera's mirror direction, so its highlight falls off the tile and the preview shows
no streak. For a tile whose predicted highlight is anisotropic (the traced lobe's
``anisotropy`` at least :data:`ANISOTROPY_MIN`), the preview's spot moves to the camera's
mirror image (same elevation, opposite azimuth): the streak crosses the tile's centre.

The verification renders one more small frame, the same camera and representation lit
by that spot alone (the soft box's broad reflection and the environment would otherwise
weigh in the moments), reads the highlight's second moments off it
(:func:`render.highlight.highlight_shape`), and compares them with the highlight the
predicted BRDF lobe makes in the same view (:func:`render.highlight.predicted_highlight`):
the long axes within :data:`ANGLE_TOLERANCE_DEG`, and the elongation at least
:data:`ELONGATION_SHARE` of the predicted excess over round.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from printapp.design import Design, TileBase
from render.highlight import (
    HighlightShape,
    PinholeCamera,
    SlopeLobe,
    axis_difference_deg,
    highlight_shape,
    predicted_highlight,
)
from render.mitsuba_adapter import PREVIEW_FOV_DEG, Framing, StudioLight, studio_places

if TYPE_CHECKING:
    import trimesh

    from printapp.relief import Relief

ANISOTROPY_MIN = 3.0
"""Predicted lobe anisotropy (long / short roughness) from which a tile's highlight is shown and checked.

The camera alone stretches a round highlight: the plane of incidence is foreshortened by
the sine of the elevation, and at the default 40 degrees a round lobe's highlight comes
out 1.4-1.5 times taller than wide (:func:`render.highlight.predicted_highlight`, lobes of
roughness 0.03-0.1). With the lobe's long axis across the plane of incidence, the worst
case, an anisotropy of 2 barely overcomes that (1.2-1.3 times, lying across), too round
for its axis to be read off a noisy render; from 3 it is 1.4-1.8 times, and its
direction is the lobe's (``docs/benchmarks.md``, render section).
"""
ANGLE_TOLERANCE_DEG = 20.0
"""Largest angle between the measured and the predicted long axes on the screen."""
ELONGATION_SHARE = 1.0 / 3.0
"""Share of the predicted elongation's excess over 1 that the rendered highlight must show.

Empirical: the streak is made of glints, and its length is set by the steepest strokes,
of which a small tile has few. The brushed tile (24 x 16 mm) shows 1.00 of the predicted
excess (4.85 against 4.86), a 12 x 8 mm cut of it 0.52 (3.78 against 6.90; the tests'
tile). A third keeps both with room, and is still above what the view alone gives a
round lobe (1.4-1.5 against a floor of 2.3 on the brushed tile).
"""
FRAME_WIDTH_PX = 256
FRAME_SPP = 64
"""Size and samples of the verification frame: the brushed tile's glints are steady at 64."""
EDGE_PX = 2
"""Pixels taken off the tile's top face at its edges (its rim catches light of its own)."""


@dataclass
class HighlightCheck:
    """Whether the rendered highlight lies and stretches as predicted, or why it was not checked."""

    applied: bool
    ok: bool
    sentence: str
    record: dict[str, Any] = field(default_factory=dict)
    frame: np.ndarray | None = None


def applies(design: Design, metrics: dict[str, Any]) -> tuple[bool, str]:
    """Whether the design's highlight is shown and checked, and why (or why not)."""
    anisotropy = float(metrics["highlight"]["anisotropy"])
    if not isinstance(design.base, TileBase) or design.combine:
        return False, "not a plain tile: the predicted highlight assumes a flat top face"
    if anisotropy < ANISOTROPY_MIN:
        return False, (
            f"the predicted highlight's anisotropy {anisotropy:.2f} is below {ANISOTROPY_MIN:g}: "
            "the camera's own foreshortening would set its shape on the screen"
        )
    return True, f"the predicted highlight's anisotropy {anisotropy:.2f} is at least {ANISOTROPY_MIN:g}"


def mirror_light(design: Design) -> StudioLight:
    """The studio light with its spot at the camera's mirror image (same elevation, opposite azimuth)."""
    r = design.render
    return replace(
        StudioLight(), highlight_azimuth_rad=r.azimuth_rad + math.pi, highlight_elevation_rad=r.elevation_rad
    )


def preview_light(design: Design, metrics: dict[str, Any]) -> StudioLight:
    """The studio light of a design's preview: for an anisotropic tile, the spot at the camera's mirror."""
    return mirror_light(design) if applies(design, metrics)[0] else StudioLight()


def predicted_shape(
    design: Design, relief: Relief, mesh: trimesh.Trimesh, lobe: SlopeLobe, width_px: int, height_px: int
) -> tuple[HighlightShape | None, np.ndarray]:
    """The predicted highlight's moments in the verification frame, and the tile's top face there."""
    from scipy.ndimage import binary_erosion

    r = design.render
    vertices = np.asarray(mesh.vertices)
    frame = Framing.of(vertices, width_px, height_px, PREVIEW_FOV_DEG, r.distance_scale)
    places = studio_places(frame, r.elevation_rad, r.azimuth_rad, mirror_light(design), r.distance_scale)
    camera = PinholeCamera(tuple(places.eye), tuple(frame.centre), PREVIEW_FOV_DEG, width_px, height_px)
    patch = relief.patch
    assert isinstance(design.base, TileBase)
    plane = design.base.thickness_mm + float(np.mean(patch.heights_mm))
    rect = (
        patch.origin_x_mm,
        patch.origin_x_mm + patch.width_mm,
        patch.origin_y_mm,
        patch.origin_y_mm + patch.depth_mm,
    )
    image, mask = predicted_highlight(camera, tuple(places.spot), places.spot_half_size_mm, lobe, plane, rect)
    mask = binary_erosion(mask, iterations=EDGE_PX)
    return highlight_shape(image, mask), mask


def lobe_of(metrics: dict[str, Any]) -> SlopeLobe:
    """The predicted lobe's slopes, from ``metrics["highlight"]`` (:func:`render.brdf_fit.lobe_alpha`)."""
    h = metrics["highlight"]
    return SlopeLobe(float(h["alpha_long"]), float(h["alpha_short"]), math.radians(float(h["azimuth_deg"])))


def verdict(
    measured: HighlightShape | None, predicted: HighlightShape | None, lobe: SlopeLobe
) -> tuple[bool, str, dict[str, Any]]:
    """Compare the measured highlight with the predicted one: (ok, sentence, record)."""
    where = (
        f"predicted from the BRDF lobe (long axis {math.degrees(lobe.azimuth_rad) % 180:.1f} deg "
        "on the tile, "
        f"anisotropy {lobe.alpha_long / lobe.alpha_short:.2f})"
    )
    if predicted is None or measured is None:
        what = "predicted" if predicted is None else "rendered"
        return False, f"highlight: the {what} frame shows no highlight on the tile's top face", {}
    floor = 1.0 + ELONGATION_SHARE * (predicted.elongation - 1.0)
    angle = axis_difference_deg(measured.angle_deg, predicted.angle_deg)
    ok = angle <= ANGLE_TOLERANCE_DEG and measured.elongation >= floor
    record = {
        "measured_angle_deg": round(measured.angle_deg, 2),
        "predicted_angle_deg": round(predicted.angle_deg, 2),
        "angle_difference_deg": round(angle, 2),
        "tolerance_deg": ANGLE_TOLERANCE_DEG,
        "measured_elongation": round(measured.elongation, 3),
        "predicted_elongation": round(predicted.elongation, 3),
        "elongation_floor": round(floor, 3),
        "measured_centroid_px": [round(v, 1) for v in measured.centroid_px],
        "predicted_centroid_px": [round(v, 1) for v in predicted.centroid_px],
    }
    sentence = (
        f"the highlight's long axis on the screen lies at {measured.angle_deg:.1f} deg "
        "(measured, spot-lit frame) "
        f"against {predicted.angle_deg:.1f} deg {where}: {angle:.1f} deg apart "
        f"({'within' if angle <= ANGLE_TOLERANCE_DEG else 'more than'} {ANGLE_TOLERANCE_DEG:g}); "
        f"it is {measured.elongation:.2f} times longer than wide (predicted {predicted.elongation:.2f}, "
        f"at least {floor:.2f} asked)"
    )
    return ok, sentence, record


def frame_size(design: Design) -> tuple[int, int]:
    """Width and height (pixels) of the verification frame: the preview's aspect, at most 256 wide."""
    r = design.render
    width = min(FRAME_WIDTH_PX, r.width_px)
    return width, max(16, round(width * r.height_px / r.width_px))


def spot_only(design: Design) -> StudioLight:
    """The verification frame's light: the mirror spot alone (no soft box, no environment)."""
    return replace(mirror_light(design), radiance=0.0, environment=0.0)


def check_highlight(
    design: Design,
    relief: Relief,
    mesh: trimesh.Trimesh,
    metrics: dict[str, Any],
    frame: np.ndarray | None,
    *,
    lobe: SlopeLobe | None = None,
) -> HighlightCheck:
    """Compare the highlight of the spot-lit verification ``frame`` (linear RGB) with the prediction.

    ``frame`` is :func:`printapp.rendering.highlight_frame`'s render (None where
    :func:`applies` said no); ``lobe`` replaces the predicted lobe (tests turn it, to see
    the check fail).
    """
    ok_to_apply, why = applies(design, metrics)
    if ok_to_apply and frame is None:
        ok_to_apply, why = False, "no frame was rendered (rendering is off)"
    if not ok_to_apply:
        record = {"applied": False, "why": why}
        return HighlightCheck(False, True, f"highlight direction not checked: {why}", record)
    height, width = frame.shape[:2]
    lobe = lobe or lobe_of(metrics)
    expected, mask = predicted_shape(design, relief, mesh, lobe, width, height)
    measured = highlight_shape(frame @ np.array([0.2126, 0.7152, 0.0722]), mask)
    ok, sentence, record = verdict(measured, expected, lobe)
    light = mirror_light(design)
    record = {
        "applied": True,
        "why": why,
        "frame_px": [width, height],
        "spp": FRAME_SPP,
        "spot_azimuth_deg": round(math.degrees(light.highlight_azimuth_rad), 3),
        "spot_elevation_deg": round(math.degrees(light.highlight_elevation_rad), 3),
        **record,
    }
    return HighlightCheck(True, ok, sentence, record, frame)
