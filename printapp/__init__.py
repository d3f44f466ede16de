"""printapp: appearance printing, from a design file to a verified, printable model.

The application room: command line, design schema, pipeline, mesh building, I/O and
benchmarks. The numerics live in the packages ``noise``, ``slicing`` and ``render``,
which never import this one.
"""

__version__ = "0.1.0"
