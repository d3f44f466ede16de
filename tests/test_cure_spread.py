"""Lateral cure spread (slicing.printed.spread_dose): a Gaussian spot on square pixels, closed forms;
its place in the as-printed relief, and what it does to the staircase walls' axis-aligned facets."""

import math

import numpy as np
import pytest

from slicing.printed import CureModel, printed_heights, spread_dose


def phi(x):
    return 0.5 * (1.0 + np.vectorize(math.erf)(np.asarray(x) / math.sqrt(2.0)))


@pytest.mark.parametrize("sigma", [0.3, 0.8, 2.0])
def test_a_lit_half_plane_gives_the_normal_cdf_beyond_its_edge(sigma):
    dose = np.zeros((64, 96))
    dose[:, :48] = 1.0  # lit left of x = 48 (pixel edges at integers, centres at k + 1/2)
    spread = spread_dose(dose, sigma)
    x = np.arange(96) + 0.5 - 48.0
    inner = slice(32, 64)  # far from the image's own edges (unlit beyond them)
    np.testing.assert_allclose(spread[32, inner], phi(-x[inner] / sigma), atol=1e-6)


@pytest.mark.parametrize("sigma", [0.4, 1.1])
def test_inside_the_pixels_too(sigma):
    dose = np.zeros((8, 40))
    dose[:, :20] = 1.0
    spread = spread_dose(dose, sigma, 0.0, oversample=3)
    assert spread.shape == (24, 120)
    x = (np.arange(120) + 0.5) / 3.0 - 20.0  # the sub-squares' centres, in pixels from the edge
    np.testing.assert_allclose(spread[5, 30:90], phi(-x[30:90] / sigma), atol=1e-6)


def test_without_spread_each_point_takes_its_own_pixel():
    rng = np.random.default_rng(4)
    dose = rng.random((5, 7))
    np.testing.assert_array_equal(spread_dose(dose, 0.0, oversample=3), np.kron(dose, np.ones((3, 3))))


def test_one_lit_pixel_spreads_as_the_psf_integrated_over_it_and_keeps_its_dose():
    dose = np.zeros((41, 41))
    dose[20, 20] = 1.0
    sx, sy = 0.7, 1.3  # different along columns (x) and rows (y)
    spread = spread_dose(dose, sx, sy)
    k = np.arange(41) - 20.0
    wx = phi((k + 0.5) / sx) - phi((k - 0.5) / sx)
    wy = phi((k + 0.5) / sy) - phi((k - 0.5) / sy)
    np.testing.assert_allclose(spread, np.outer(wy, wx), atol=1e-9)  # the PSF stops at 5 sigma
    assert spread.sum() == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_array_equal(spread_dose(dose, 0.0), dose)  # no spread, no change


def test_bad_spreads_are_refused():
    with pytest.raises(ValueError, match="sigma"):
        spread_dose(np.zeros((4, 4)), -1.0)
    with pytest.raises(ValueError, match="2-D"):
        spread_dose(np.zeros(4), 1.0)
    with pytest.raises(ValueError, match="oversample"):
        spread_dose(np.zeros((4, 4)), 1.0, oversample=0)


class _StepSlices:
    """Layers as printed_heights reads them: four layers lit right of a pixel boundary, over a full base."""

    def __init__(self, profile, rows=12, cols=40, base=6, step=4):
        self.profile, self.rows, self.cols = profile, rows, cols
        self.layer_height_mm = 0.05
        self._base, self._step = base, step

    def coverages(self):
        for k in range(self._base + self._step):
            cov = np.ones((self.rows, self.cols))
            if k >= self._base:
                cov[:, : self.cols // 2] = 0.0  # lit from column 20 on: the edge at x = 20 px
            yield k, cov

    def grey(self, coverage):
        return np.round(coverage * 255.0).astype(np.uint8)


def test_a_step_cures_each_layer_by_the_working_curve_of_the_spread_dose():
    from printapp.cure import build_cure_model
    from slicing import find_printer

    profile = find_printer("prusa-sl1")
    cure = build_cure_model("working-curve", None)
    slices = _StepSlices(profile)
    sigma_mm = 0.02
    plain = printed_heights(slices, cure)
    spread = printed_heights(slices, cure, sigma_mm)
    row, edge = 6, 20
    assert plain[row, edge] - plain[row, edge - 1] == pytest.approx(4 * 0.05)  # a sharp step of 4 layers
    # Independent: each layer of the step is a half-plane lit beyond the edge, dose Phi(d / sigma) at
    # a distance d inside it; Jacobs' working curve cures min(t, Dp ln(E / Ec)) of it, nothing below Ec.
    for col in range(edge - 3, edge + 3):
        d_mm = (col + 0.5 - edge) * profile.pitch_x_mm
        e = float(phi(d_mm / sigma_mm)) * cure.full_dose
        depth = (
            cure.penetration_depth_mm * math.log(e / cure.critical_dose) if e > cure.critical_dose else 0.0
        )
        assert spread[row, col] - spread[row, 2] == pytest.approx(4 * min(0.05, depth), abs=1e-9)
    # Far from the edge the spread changes nothing (the base's layers are lit everywhere).
    assert spread[row, 10] == pytest.approx(plain[row, 10]) and spread[row, 30] == pytest.approx(
        plain[row, 30]
    )
    # Three points per pixel: the step's wall is drawn inside the pixels.
    fine = printed_heights(slices, cure, sigma_mm, oversample=3)
    assert fine.shape == (36, 120)
    np.testing.assert_allclose(fine[1::3, 1::3], spread, atol=1e-12)  # the middle points are the centres


def _axis_share(h: np.ndarray, pitch: float) -> float:
    """Share of the tilted facets (slope above 0.05) whose normal lies within 5 degrees of the x or y axis."""
    from render.gonio import facet_slopes

    fx, fy = facet_slopes(h, pitch, pitch)
    a, b = np.asarray(fx).ravel(), np.asarray(fy).ravel()
    keep = np.hypot(a, b) > 0.05
    az = np.degrees(np.arctan2(b[keep], a[keep])) % 90.0
    return float(np.mean(np.minimum(az, 90.0 - az) < 5.0))


def test_the_spread_turns_a_staircase_s_walls_towards_the_outline_it_draws():
    # A disc of one layer on binary pixels: its outline is a staircase of pixel edges along x and y.
    # Seen three points per pixel, with no spread nearly every wall faces along an axis; a wider spread
    # rounds the staircase towards the circle it draws, whose walls face every way.
    n, pitch, m = 48, 0.05, 3
    yy, xx = np.indices((n, n)) + 0.5
    radius = 0.4 * n
    dose = ((xx - n / 2) ** 2 + (yy - n / 2) ** 2 < radius**2).astype(float)
    linear = CureModel.linear()
    share = {}
    for sigma_px in (0.0, 0.42, 1.0, 2.0):
        grey = 255.0 * np.clip(spread_dose(dose, sigma_px, oversample=m), 0.0, 1.0)
        share[sigma_px] = _axis_share(linear.thickness_mm(grey, 0.05), pitch / m)
    assert share[0.0] > 0.9
    assert share[0.0] > share[0.42] > share[1.0] > share[2.0]
    # Independent: the circle itself, blurred, on the same points (10/90 of its walls near an axis).
    fy, fx = (np.indices((n * m, n * m)) + 0.5) / m
    circle = 0.05 * phi((radius - np.hypot(fx - n / 2, fy - n / 2)) / 2.0)
    assert _axis_share(circle, pitch / m) == pytest.approx(10.0 / 90.0, abs=0.02)
    assert share[2.0] == pytest.approx(_axis_share(circle, pitch / m), abs=0.06)


def test_a_design_s_cure_spread_reaches_its_as_printed_relief():
    from printapp.design import design_from_dict
    from printapp.design_io import resolved_toml
    from printapp.relief import appearance_field, cure_spread, nominal_cure_spread_mm

    base = {"base": {"width_mm": 6.0, "depth_mm": 5.0}, "relief": {"amplitude_um": 200}}
    plain = design_from_dict(base)
    spread = design_from_dict({**base, "printer": {"name": "prusa-sl1", "cure_spread_um": 20}})
    assert cure_spread(plain)[0] == 0.0 and "none (default" in cure_spread(plain)[1]
    assert cure_spread(spread) == (pytest.approx(0.02), "20 um ([printer] cure_spread_um)")
    assert nominal_cure_spread_mm(plain) == pytest.approx(0.04725 / 2.3548, rel=1e-4)
    assert "cure_spread_mm = 0.02" in resolved_toml(spread)
    a, _ = appearance_field(plain)
    b, _ = appearance_field(spread)
    assert a.shape == b.shape
    # The same layers, cured from a spread dose: the steps between pixels are gentler.
    sa, sb = np.hypot(*a.slopes()), np.hypot(*b.slopes())
    assert float(np.sqrt(np.mean(sb**2))) < float(np.sqrt(np.mean(sa**2)))
    assert abs(float(b.heights_mm.mean()) - float(a.heights_mm.mean())) < 0.01
