"""The bench package's rules: it measures the public API, and it works from an installed wheel.

Checked on the source with ``ast``, nothing imported: a benchmark may use private names
of its own package only; nothing in ``printapp`` imports from ``tests``; the bench finds
its files as package resources, never relative to a checkout; every stage has its module.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
BENCH = ROOT / "printapp" / "bench"
BENCH_MODULES = sorted(BENCH.rglob("*.py"))


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _absolute(node: ast.ImportFrom, path: Path, root: Path) -> str:
    """The module an ``import from`` names, relative imports resolved against ``path``."""
    if node.level == 0:
        return node.module or ""
    package = _module_name(path, root).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    base = package[: len(package) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _inside_bench(module: str) -> bool:
    return module == "printapp.bench" or module.startswith("printapp.bench.")


def _dotted(node: ast.expr) -> list[str] | None:
    """``a.b.c`` as ``["a", "b", "c"]``; None unless the chain starts at a plain name."""
    names = []
    while isinstance(node, ast.Attribute):
        names.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return [node.id, *reversed(names)]


def private_uses(path: Path, root: Path = ROOT) -> list[str]:
    """Private names of modules outside printapp.bench that the module at ``path`` uses."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found: list[str] = []
    outside: set[str] = set()  # local names bound to modules (or objects) from outside the bench
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if _inside_bench(alias.name):
                    continue
                if any(_private(part) for part in alias.name.split(".")):
                    found.append(f"import {alias.name}")
                outside.add(alias.asname or alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            module = _absolute(node, path, root)
            if _inside_bench(module):
                continue
            if any(_private(part) for part in module.split(".")):
                found.append(f"from {module} import ...")
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"from {module} import {alias.name}")
                outside.add(alias.asname or alias.name)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            chain = _dotted(node)
            if chain and chain[0] in outside and any(_private(part) for part in chain[1:]):
                found.append(".".join(chain))
    return sorted(set(found))


def test_the_check_sees_private_imports_and_attributes(tmp_path):
    folder = tmp_path / "printapp" / "bench"
    folder.mkdir(parents=True)
    probe = folder / "probe.py"
    probe.write_text(
        "from __future__ import annotations\n"
        "import render.gonio\n"
        "from render.gonio import _trace, lobe_bins\n"
        "from render import mitsuba_adapter as ma\n"
        "from miepython import _backend\n"
        "from .timing import _private_helper\n"
        "from .. import _outside\n"
        "ma._mesh_object(1)\n"
        "render.gonio._primary_origin(2)\n"
        "print(lobe_bins.__doc__)\n"
    )
    assert private_uses(probe, tmp_path) == [
        "from miepython import _backend",
        "from printapp import _outside",
        "from render.gonio import _trace",
        "ma._mesh_object",
        "render.gonio._primary_origin",
    ]


@pytest.mark.parametrize("path", BENCH_MODULES, ids=lambda p: str(p.relative_to(BENCH)))
def test_benchmarks_use_only_public_names_of_other_modules(path):
    assert private_uses(path) == []


def test_nothing_in_printapp_imports_from_tests():
    for path in (ROOT / "printapp").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            assert not any(n == "tests" or n.startswith("tests.") for n in names), path


@pytest.mark.parametrize("path", BENCH_MODULES, ids=lambda p: str(p.relative_to(BENCH)))
def test_the_bench_finds_its_files_as_package_resources(path):
    # A path built from __file__ or a patched sys.path works in a checkout only, not from a wheel.
    tree = ast.parse(path.read_text(), filename=str(path))
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    attributes = {".".join(c) for n in ast.walk(tree) if isinstance(n, ast.Attribute) and (c := _dotted(n))}
    assert "__file__" not in names
    assert not {"sys.path", "importlib.util.spec_from_file_location"} & attributes


def test_every_stage_has_a_module_named_after_it():
    tree = ast.parse((BENCH / "__init__.py").read_text())
    stages = next(
        node.value
        for node in tree.body
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", None) == "STAGES"
    )
    names = [key.value for key in stages.keys]
    assert names == [
        *("noise", "frames", "lic", "surface", "slice", "mesh", "brdf"),
        *("pitch", "adaptive", "mie", "pipeline", "fit", "render", "sampling", "scale", "translucency"),
        "commands",
        *("solve", "sweep"),
    ]
    for name in names:
        module = ast.parse((BENCH / f"{name}.py").read_text())
        assert f"bench_{name}" in {n.name for n in module.body if isinstance(n, ast.FunctionDef)}, name
