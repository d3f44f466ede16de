"""The project's layout rules: `noise` is ours, and nothing below imports `printapp`."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent


def test_import_noise_is_ours():
    import noise

    assert Path(noise.__file__).resolve().parent == (ROOT / "noise").resolve()
    assert hasattr(noise, "sparse_convolution")


@pytest.mark.parametrize("package", ["noise", "slicing", "render"])
def test_lower_rooms_do_not_import_printapp(package):
    for path in (ROOT / package).rglob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            assert not any(n == "printapp" or n.startswith("printapp.") for n in names), path


def test_importing_noise_does_not_pull_in_heavy_libraries():
    import subprocess
    import sys

    code = (
        "import sys, noise, slicing, render;"
        "print(sorted(m for m in ('mitsuba', 'pyvista', 'trimesh') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
