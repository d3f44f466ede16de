"""Arbitrary TOML documents and values: the loader raises only DesignError, never anything else."""

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from printapp.design import Design, DesignError, design_from_dict
from printapp.design_io import load_design

KEYS = ["name", "base", "texture", "relief", "printer", "material", "appearance", "render", "shape", "path"]
for model in Design.model_fields.values():
    annotation = model.annotation
    for cls in getattr(annotation, "__args__", (annotation,)):
        KEYS.extend(getattr(cls, "model_fields", {}))
KEYS += ["amplitude_um", "angle_deg", "width_cm", "elevation_deg"]

scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
    st.dates(),
)
keys = st.one_of(st.sampled_from(KEYS), st.text(min_size=1, max_size=8))
values = st.recursive(
    scalars,
    lambda children: st.one_of(st.lists(children, max_size=4), st.dictionaries(keys, children, max_size=5)),
    max_leaves=20,
)


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(keys, values, max_size=8))
def test_only_design_errors_come_out(document):
    try:
        design = design_from_dict(document, "fuzz.toml")
    except DesignError as exc:
        assert str(exc).startswith("fuzz.toml")
    else:
        assert isinstance(design, Design)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.dictionaries(keys, values, max_size=6))
def test_documents_through_the_file_loader(tmp_path, document):
    path = tmp_path / "d.toml"
    try:
        path.write_text(tomli_w.dumps(document))
    except (TypeError, ValueError):
        return  # not representable in TOML (e.g. mixed arrays in old writers); nothing to load
    try:
        design = load_design(path)
    except DesignError as exc:
        assert str(exc).startswith(str(path))
    else:
        assert isinstance(design, Design)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.text(max_size=200))
def test_arbitrary_text_files(tmp_path, text):
    path = tmp_path / "t.toml"
    path.write_bytes(text.encode("utf-8", errors="surrogatepass"))
    try:
        design = load_design(path)
    except DesignError as exc:
        assert str(exc).startswith(str(path))
    else:
        assert isinstance(design, Design)
