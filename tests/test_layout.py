"""The project's layout rules (README, "How the code is laid out"), read from the code with ``ast``.

- the rooms ``noise``, ``slicing`` and ``render`` import only what their row of the table
  allows (and never ``printapp``); ``printapp`` imports anything;
- no import cycles between the project's modules, counting imports inside functions
  and under ``TYPE_CHECKING`` (they hide a cycle, they do not remove it);
- no private name (``_name``) is imported from another top-level package;
- nothing in the project imports the tests;
- the rooms neither print nor open files;
- no module is over 600 lines unless its docstring says why it must be one piece, and
  no command-line module is over 300 lines;
- the command modules keep their annotations as objects, and ``printapp slice`` starts
  without pydantic, trimesh or Mitsuba.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
PACKAGES = ("noise", "slicing", "render", "printapp")
STDLIB = set(sys.stdlib_module_names)

MAY_IMPORT: dict[str, set[str]] = {
    "noise": {"numpy", "numba", "scipy"},
    "slicing": {"numpy", "numba", "PIL", "isal", "zlib_ng", "noise"},
    "render": {"numpy", "numba", "scipy", "mitsuba", "drjit", "pyvista", "noise"},
}
"""Third-party libraries and project rooms each lower room may import (the standard library always)."""
NOISE_MODULES = {
    "slicing": {"noise.heightfield", "noise.lazy"},
    "render": {"noise.heightfield", "noise.hashing", "noise.frames", "noise.lazy"},
}
"""What of ``noise`` the other lower rooms may use: its types, hashing, frames, lazy exports; no textures."""


def _modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join(parts)] = path
    return found


MODULES = _modules()


def _imports(name: str, path: Path) -> list[tuple[str, list[str], int]]:
    """(module imported, names taken from it, line) for every import in the file, at any depth."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(alias.name, [], node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - (node.level - 1)]
                base = ".".join(parts + ([base] if base else []))
            out.append((base, [alias.name for alias in node.names], node.lineno))
    return out


def _project_module(dotted: str) -> str | None:
    while dotted and dotted not in MODULES:
        dotted = dotted.rpartition(".")[0]
    return dotted or None


def test_import_noise_is_ours():
    import noise

    assert Path(noise.__file__).resolve().parent == (ROOT / "noise").resolve()
    assert hasattr(noise, "sparse_convolution")


@pytest.mark.parametrize("room", ["noise", "slicing", "render"])
def test_each_room_imports_only_what_its_row_allows(room):
    bad = []
    for name, path in MODULES.items():
        if name.split(".")[0] != room:
            continue
        for module, _, line in _imports(name, path):
            top = module.split(".")[0]
            if top in STDLIB or top == room:
                continue
            if top not in MAY_IMPORT[room]:
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
            elif top == "noise" and room in NOISE_MODULES:
                target = _project_module(module) or module
                if target not in NOISE_MODULES[room] and module not in NOISE_MODULES[room]:
                    bad.append(
                        f"{path.relative_to(ROOT)}:{line} imports {module} (only {NOISE_MODULES[room]})"
                    )
    assert not bad, "\n".join(bad)


def _graph() -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {name: set() for name in MODULES}
    for name, path in MODULES.items():
        for module, names, _ in _imports(name, path):
            targets = [f"{module}.{n}" if f"{module}.{n}" in MODULES else module for n in names] or [module]
            for target in targets:
                resolved = _project_module(target)
                if resolved and resolved != name:
                    edges[name].add(resolved)
    return edges


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycles():
    assert _cycles(_graph()) == []


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_private_names_across_packages():
    bad = []
    for name, path in MODULES.items():
        for module, names, line in _imports(name, path):
            if module.split(".")[0] in PACKAGES and module.split(".")[0] != name.split(".")[0]:
                private = [n for n in names if n.startswith("_")]
                private += [module] if any(p.startswith("_") for p in module.split(".")) else []
                if private:
                    bad.append(f"{path.relative_to(ROOT)}:{line} takes {private} from {module}")
    assert not bad, "\n".join(bad)


def test_nothing_imports_the_tests():
    bad = [
        f"{path.relative_to(ROOT)}:{line}"
        for name, path in MODULES.items()
        for module, _, line in _imports(name, path)
        if module == "tests" or module.startswith("tests.")
    ]
    assert not bad


@pytest.mark.parametrize("room", ["noise", "slicing", "render"])
def test_rooms_neither_print_nor_open_files(room):
    bad = []
    for name, path in MODULES.items():
        if name.split(".")[0] != room:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id in ("print", "open")
            ):
                bad.append(f"{path.relative_to(ROOT)}:{node.lineno} calls {node.func.id}()")
    assert not bad, "\n".join(bad)


def test_modules_are_small_or_say_why_not():
    bad = []
    for name, path in MODULES.items():
        text = path.read_text(encoding="utf-8")
        lines = text.count("\n")
        limit = 300 if name.startswith("printapp.cli") else 600
        doc = ast.get_docstring(ast.parse(text)) or ""
        if lines > limit and (limit == 300 or "one piece" not in doc.lower()):
            bad.append(f"{path.relative_to(ROOT)}: {lines} lines (limit {limit})")
    assert not bad, "\n".join(bad)


def test_importing_the_rooms_does_not_pull_in_heavy_libraries():
    code = (
        "import sys, noise, slicing, render;"
        "print(sorted(m for m in ('mitsuba', 'pyvista', 'trimesh') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def _fresh_python(code: str) -> subprocess.CompletedProcess[str]:
    """``code`` run by a fresh interpreter in the checkout: what a user's first import sees."""
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_light_modules_load_without_numba_or_scipy():
    """What `printapp emboss` and the design schema import stays light (issue #20): the packages
    resolve their re-exported kernels on first use (noise/lazy.py), and a name that is also a
    submodule's (``noise.veins``) is still the function once that submodule has been imported."""
    code = (
        "import sys\n"
        "import noise.heightfield, printapp.exporters, printapp.slab, printapp.emboss, printapp.topography\n"
        "from slicing import find_printer\n"
        "assert 'numba' not in sys.modules and 'scipy' not in sys.modules, sorted(sys.modules)\n"
        "import noise.veins, noise\n"
        "assert callable(noise.veins) and callable(noise.cellular) and 'numba' in sys.modules\n"
    )
    result = _fresh_python(code)
    assert result.returncode == 0, result.stderr[-2000:]


def test_the_command_line_starts_light():
    """Every command pays for typer reading every command's signature (issue #20): the command
    modules keep their annotations as objects (typer would evaluate strings, about 0.02 s a run),
    and `printapp slice` reaches its work without pydantic (typer 0.29 imports it and builds a
    TypeAdapter per parameter, 0.1-0.3 s a run; pyproject.toml keeps typer below it)."""
    lazy = [
        path.name
        for path in sorted((ROOT / "printapp" / "cli").glob("*_cmds.py"))
        if any(
            isinstance(node, ast.ImportFrom) and node.module == "__future__"
            for node in ast.parse(path.read_text(encoding="utf-8")).body
        )
    ]
    assert not lazy, f"string annotations in {lazy}"
    code = (
        "import sys\n"
        "import printapp.slicer as s\n"
        "from printapp.cli import app\n"
        "def stop(*args, **kwargs):\n"
        "    raise SystemExit(sorted(m for m in ('pydantic', 'trimesh', 'mitsuba') if m in sys.modules))\n"
        "s.slice_model_file = stop\n"
        "app(['slice', 'model.stl', '-o', 'model.sl1', '-q'], standalone_mode=False)\n"
    )
    result = _fresh_python(code)
    assert result.returncode == 1 and result.stderr.strip().endswith("[]"), result.stderr[-2000:]
