"""Slow, independent reference implementations that the benchmarks and the tests measure against.

Each is written from the published formulas, not from printapp's kernels: sparse
convolution noise in plain Python integers (:mod:`.scn_reference`) and per point in
numba (:mod:`.scn_plain_numba`, the baseline of ``printapp bench noise``), Lorenz-Mie
with mpmath's Bessel functions (:mod:`.mie_mpmath`, needs mpmath), ray-triangle first
hits by brute force (:mod:`.ray_triangles`) and the albedo of a half-space by a random
walk (:mod:`.albedo_mc`).
"""
