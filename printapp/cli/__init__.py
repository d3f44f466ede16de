"""The ``printapp`` command line: a package of thin commands, one module per group.

Each command parses its options, calls one application function of ``printapp``, and
prints the result; :mod:`printapp.cli.app` holds the application, the consoles and the
one error boundary. Heavy libraries are imported inside the commands that need them,
so ``printapp --help`` starts fast. The command modules keep their annotations as objects
(no ``from __future__ import annotations``): typer reads the signature of every command on
every run, and evaluating them from strings cost each command about 0.02 s.
"""

# ruff: noqa: I001 (the import order is the order ``printapp --help`` lists the commands)
from printapp.cli.app import app, main
from printapp.cli import design_cmds  # noqa: F401 (registers demo, design)
from printapp.cli import texture_cmds  # noqa: F401 (texture, fit)
from printapp.cli import mesh_cmds  # noqa: F401 (heightmap, emboss, displace, preview)
from printapp.cli import slice_cmds  # noqa: F401 (printers, slice)
from printapp.cli import appearance_cmds  # noqa: F401 (brdf, render)
from printapp.cli import material_cmds  # noqa: F401 (material)
from printapp.cli import solve_cmds  # noqa: F401 (solve, sweep)
from printapp.cli import bench_cmds  # noqa: F401 (bench)

__all__ = ["app", "main"]
