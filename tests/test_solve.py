"""Design for a look: the cure models, exposure from heights, the surrogate, and ``printapp solve``."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from noise.heightfield import HeightField
from slicing import PRINTERS
from slicing.exposure import expose_heightfield
from slicing.printed import CureModel, pixel_centres_mm, printed_heights

ROOT = Path(__file__).parent.parent
SL1 = PRINTERS["prusa-sl1"]
SMALL = {"base": {"width_mm": 5.0, "depth_mm": 5.0, "thickness_mm": 1.0}, "brdf": {"rays": 5000}}


def printapp(*args: object) -> subprocess.CompletedProcess:
    """The ``printapp`` console script beside this interpreter."""
    exe = Path(sys.executable).with_name("printapp")
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, timeout=600)


def test_working_curve_against_its_closed_form():
    dp, ec, dose, layer = 0.1, 10.0, 30.0, 0.05
    cure = CureModel.working_curve(dp, ec, dose)
    grey = np.arange(256.0)
    energy = dose * grey / 255.0
    closed = np.where(energy > ec, np.minimum(dp * np.log(np.maximum(energy, 1e-300) / ec), layer), 0.0)
    assert np.array_equal(cure.thickness_mm(grey, layer), closed)
    assert cure.full_cure_depth_mm == pytest.approx(dp * math.log(3.0))
    assert cure.threshold_grey() == pytest.approx(85.0)
    saturation = 255.0 * math.exp(-(dp * math.log(3.0) - layer) / dp)
    assert cure.saturation_grey(layer) == pytest.approx(saturation)
    assert cure.thickness_mm(85.0, layer) == 0.0 < cure.thickness_mm(86.0, layer)
    assert cure.thickness_mm(math.ceil(saturation), layer) == layer
    # The inverse picks the grey level whose thickness is nearest: within half the step between
    # the two grey levels around the exact one.
    wanted = np.linspace(0.001, layer - 0.001, 400)
    got = cure.thickness_mm(cure.grey_for_thickness(wanted, layer), layer)
    lo = np.floor(255.0 * ec / dose * np.exp(wanted / dp))
    step = cure.thickness_mm(np.minimum(lo + 1.0, 255.0), layer) - cure.thickness_mm(lo, layer)
    assert np.all(np.abs(got - wanted) <= 0.5 * step + 1e-12)
    assert np.max(step) < 0.0015  # 8 bits resolve the layer to about a micrometre
    assert cure.grey_for_thickness(np.array([0.0, layer]), layer).tolist() == [0, 255]
    linear = CureModel.linear()
    assert np.array_equal(linear.thickness_mm(grey, layer), layer * grey / 255.0)
    with pytest.raises(ValueError, match="would cure nothing"):
        CureModel.working_curve(dp, 30.0, 20.0)


def test_grey_levels_print_a_sub_layer_height_as_the_closed_form_says():
    """A flat relief 2.7 layers above the base: two full layers and a grey one, whose grey level the
    working curve turns back into 0.7 of a layer (to within 8 bits); binary pixels print the layer
    whole, as its slice plane (its middle) lies below the top."""
    field = HeightField(np.full((60, 60), 0.135), 0.05, 0.05)
    cure = CureModel.working_curve(0.1, 10.0, 30.0)
    for grey_levels, expected in ((True, 1.135), (False, 1.15)):
        slices = expose_heightfield(field, 1.0, SL1, cure=cure, grey_levels=grey_levels)
        heights = printed_heights(slices, cure)
        x, y = pixel_centres_mm(slices)
        inside = np.isfinite(slices.target_top_mm)
        assert inside.sum() > 0.8 * 60 * 60 * (0.05 / SL1.pitch_mm) ** 2 * 0.8
        top = heights[inside]
        assert np.all(np.abs(top - expected) < 0.0005), (grey_levels, top.min(), top.max())
        assert len(x) == slices.cols and len(y) == slices.rows


def test_the_linear_model_is_the_old_as_printed_relief():
    from printapp.design import design_from_dict
    from printapp.relief import build_relief, slice_tile

    design = design_from_dict({**SMALL, "material": {"cure": "linear"}})
    slices = slice_tile(design, build_relief(design).patch)
    old = np.zeros((slices.rows, slices.cols))
    for k, cov in slices.coverages():
        thickness = SL1.initial_layer_height_mm if k == 0 else slices.layer_height_mm
        old += thickness * slices.grey(cov) / 255.0
    assert np.array_equal(printed_heights(slices), old)
    assert np.array_equal(printed_heights(slices, CureModel.linear()), old)


def test_the_cure_models_and_grey_levels_move_the_gloss_the_way_they_should():
    """The working curve turns anti-aliased grey into all or nothing: sharper terraces, more mirror,
    more gloss than the linear model. Grey levels set from the heights fill the terraces in: the
    flat tops go and the gloss falls."""
    from printapp.design import design_from_dict
    from printapp.evaluate import evaluate_design

    def gloss(**tables: dict) -> dict:
        design = design_from_dict({**SMALL, **tables})
        return evaluate_design(design, "brdf")["metrics"]

    linear = gloss(material={"cure": "linear"})
    working = gloss(material={"cure": "working-curve"})
    grey = gloss(relief={"grey_levels": True})
    assert working["gloss_60"] > linear["gloss_60"] + 3.0
    assert working["surrogate_flat_fraction"] > linear["surrogate_flat_fraction"]
    assert grey["gloss_60"] < working["gloss_60"] - 20.0
    assert grey["surrogate_flat_fraction"] < 0.1


def test_the_traced_glossmeter_is_predict_appearance_bit_for_bit():
    from printapp.design import design_from_dict
    from printapp.evaluate import traced_metrics
    from printapp.relief import appearance_field, build_relief
    from printapp.rendering import predict_for_design

    design = design_from_dict(
        {
            **SMALL,
            "texture": {"kind": "scn", "stretch": 4.0, "angle_deg": 30.0},
            "brdf": {"rays": 5000, "theta_bins": 18, "phi_bins": 36},  # a quick fit
        }
    )
    field, _ = appearance_field(design, build_relief(design))
    fast, full = traced_metrics(design, field), predict_for_design(design, field).metrics
    assert fast["gloss_gu"] == full["gloss_gu"] and fast["haze"] == full["haze"]
    for key in ("alpha_long", "alpha_short", "anisotropy", "azimuth_deg"):
        assert fast["highlight"][key] == full["highlight"][key]


def test_the_surrogate_is_close_to_the_tracer():
    from printapp.design import design_from_dict
    from printapp.evaluate import evaluate_design

    for tables in ({}, {"relief": {"grey_levels": True}}, {"relief": {"pixel_texture_um": 30}}):
        m = evaluate_design(design_from_dict({**SMALL, **tables}), "brdf")["metrics"]
        for angle in (20, 60):
            assert abs(m[f"gloss_{angle}"] - m[f"surrogate_gloss_{angle}"]) < 6.0, (tables, angle, m)


@pytest.mark.slow
def test_targets_taken_from_a_prediction_are_met_again_from_a_perturbed_start(tmp_path):
    from printapp.design import design_from_dict
    from printapp.engine import Engine
    from printapp.evaluate import evaluate_design
    from printapp.solve import solve_design

    known = {
        "base": {"width_mm": 5.0, "depth_mm": 5.0, "thickness_mm": 1.0},
        "texture": {"kind": "scn", "feature_size_mm": 0.8, "stretch": 4.0, "angle_deg": 60.0, "seed": 2},
        "relief": {"amplitude_um": 150, "grey_levels": True},
        "brdf": {"rays": 20000},
    }
    truth = evaluate_design(design_from_dict(known), "brdf")["metrics"]
    gloss, azimuth = truth["gloss_60"], truth["highlight_azimuth_deg"]
    assert 5.0 < azimuth < 175.0
    perturbed = {
        **known,
        "texture": {**known["texture"], "angle_deg": 110.0},
        "relief": {**known["relief"], "amplitude_um": 260},
        "appearance": {
            "gloss_60": {"value": gloss, "tolerance": 3.0},
            "highlight_azimuth_deg": {"value": azimuth, "tolerance": 5.0},
        },
        "solve": {
            "amplitude_um": [80, 300],
            "angle_deg": [0, 180],
            "evaluations": 40,
            "rounds": 2,
            "seed": 3,
        },
    }
    start = evaluate_design(design_from_dict(perturbed), "brdf")["metrics"]
    assert abs(start["gloss_60"] - gloss) > 3.0 or abs(start["highlight_azimuth_deg"] - azimuth) > 5.0
    with Engine(tmp_path / "cache", workers=0) as engine:
        outcome = solve_design(design_from_dict(perturbed), engine)
    assert outcome.met, (outcome.achieved, outcome.binding)
    assert abs(outcome.achieved["gloss_60"] - gloss) <= 3.0
    assert abs(outcome.achieved["highlight_azimuth_deg"] - azimuth) <= 5.0
    # Deterministic for a seed: the same search asks for the same designs, every one in the cache.
    with Engine(tmp_path / "cache", workers=0) as engine:
        again = solve_design(design_from_dict(perturbed), engine)
        assert engine.computed == 0 and engine.hits == outcome.evaluations + outcome.traced
    assert again.params == outcome.params and again.achieved == outcome.achieved


UNREACHABLE = """
[base]
width_mm = 4.0
depth_mm = 4.0
thickness_mm = 1.0
[relief]
amplitude_um = 300     # a 0.3 mm relief
[appearance]
gloss_60 = [95, 200]
[brdf]
rays = 5000
[solve]
feature_size_mm = [0.5, 2.0]
grey_levels = [false, true]
evaluations = 8
rounds = 1
confirm = 1
"""


@pytest.mark.slow
def test_an_unreachable_target_exits_3_with_the_nearest_point_and_what_binds(tmp_path):
    design = tmp_path / "shiny.toml"
    design.write_text(UNREACHABLE)
    out = tmp_path / "out"
    result = printapp("solve", design, "-o", out, "--workers", "0", "--quiet")
    assert result.returncode == 3, result.stderr
    assert "no design within the bounds meets every target" in result.stderr
    assert "gloss_60 [95, 200]" in result.stdout
    assert "binds: the resin's refractive index (1.5): a mirror-flat surface of it reaches" in result.stderr
    names = {p.name for p in out.iterdir()}
    assert {"design.nearest.toml", "solve.json"} <= names and "model.stl" not in names


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("[solve]\namplitude_um = [400, 50]\n", "solve: 'amplitude_um' must be [min, max] with min <= max"),
        ("[solve]\nstrech = [1, 4]\n", "unknown key 'solve.strech'; did you mean 'stretch'?"),
        (
            "[solve]\nkind = ['lic']\n",
            "solve: 'kind' must list distinct texture kinds among scn, fbm, turbulence",
        ),
        ("[solve]\noctaves = [2.5, 4]\n", "solve.octaves[0]: expected an integer"),
        ("", "no [solve] table"),
    ],
)
def test_a_malformed_solve_table_exits_2_naming_the_key(tmp_path, table, message):
    from typer.testing import CliRunner

    from printapp.cli import app

    design = tmp_path / "bad.toml"
    design.write_text("[appearance]\ngloss_60 = { max = 10 }\n" + table)
    result = CliRunner().invoke(app, ["solve", str(design), "-o", str(tmp_path / "out"), "--workers", "0"])
    assert result.exit_code == 2, result.stderr
    assert message in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_appearance_targets_in_every_form():
    from printapp.design import DesignError, design_from_dict
    from printapp.design_io import resolved_toml

    d = design_from_dict(
        {
            "appearance": {
                "gloss_60": {"value": 30, "tolerance": 5},
                "gloss_20": {"max": 10},
                "anisotropy": {"min": 4},
                "gloss_85": [1, 2],
                "haze": {"value": 2, "tolerance": 5},
            }
        }
    )
    a = d.appearance
    assert a.gloss_60 == (25.0, 35.0) and a.gloss_20 == (0.0, 10.0) and a.anisotropy == (4.0, 1000.0)
    assert a.gloss_85 == (1.0, 2.0) and a.haze == (0.0, 7.0)
    with pytest.raises(
        DesignError, match="'gloss_60': expected \\[min, max\\], \\{ value = V, tolerance = T \\}"
    ):
        design_from_dict({"appearance": {"gloss_60": {"value": 30}}})
    with pytest.raises(DesignError, match="crosses the ends of \\[0, 180\\] degrees"):
        design_from_dict({"appearance": {"highlight_azimuth_deg": {"value": 178, "tolerance": 5}}})
    assert design_from_dict(__import__("tomllib").loads(resolved_toml(d))).appearance == a
