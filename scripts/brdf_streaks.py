"""Where the report's cross-shaped BRDF streaks come from: the demo tile's relief, designed and as printed.

Traces each relief at normal incidence (1e6 rays, black body, 45 x 90 bins, seed 7) and prints
the share of the surface-reflection energy between 10 and 60 degrees that lies within 4 degrees of
the x and y axes (a uniform lobe puts 8.9 % there), and the share of tilted facets (slope above
0.05) whose normal lies within 5 degrees of an axis. With ``--figure PNG`` also draws the maps.

    .venv/bin/python scripts/brdf_streaks.py [--figure docs/bench/brdf_streaks.png]

About 2 minutes on 2 cores (the 3 x 3 per-pixel reliefs are 1254 x 1254).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from printapp.design_io import load_default_design
from printapp.relief import build_relief, cure_model, nominal_cure_spread_mm, slice_tile
from render.gonio import direction_from_angles, estimate_brdf, facet_slopes, projected_solid_angle
from slicing.printed import printed_heights


def axis_shares(heights: np.ndarray, pitch: float, n_phi: int = 90) -> tuple[float, float, np.ndarray]:
    """(energy share near the axes, facet share near the axes, f_specular at normal incidence)."""
    fx, fy = facet_slopes(heights, pitch, pitch)
    a, b = np.asarray(fx).ravel(), np.asarray(fy).ravel()
    keep = np.hypot(a, b) > 0.05
    az = np.degrees(np.arctan2(b[keep], a[keep])) % 90.0
    facets = float(np.mean(np.minimum(az, 90.0 - az) < 5.0))
    wi = direction_from_angles(np.radians([0.0]), np.radians([0.0]))
    table = estimate_brdf(
        heights, pitch, pitch, wi, rays=1_000_000, ior=1.5, n_theta=45, n_phi=n_phi, seed=7, periodic=False
    )
    energy = (table.f_specular[0] * projected_solid_angle(table.theta_o_edges, table.phi_o_edges))[5:30]
    centres = np.degrees(0.5 * (table.phi_o_edges[:-1] + table.phi_o_edges[1:])) % 90.0
    near = np.minimum(centres, 90.0 - centres) < 4.0
    return float(energy[:, near].sum() / energy.sum()), facets, table.f_specular[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figure", help="write the hemispherical maps to this PNG")
    args = parser.parse_args()
    design = load_default_design()
    relief = build_relief(design)
    slices = slice_tile(design, relief.patch)
    pitch = slices.profile.pitch_x_mm
    nominal = nominal_cure_spread_mm(design)
    cure = cure_model(design)
    edge = 4
    cases: list[tuple[str, np.ndarray, float]] = []
    # The designed relief at the printer's pixel centres (no layers), over the same window.
    patch = relief.patch
    ny, nx = patch.shape
    grid = (np.arange(ny) * patch.pitch_y_mm, np.arange(nx) * patch.pitch_x_mm)
    interpolate = RegularGridInterpolator(grid, patch.heights_mm)
    xs = (slices.col0 + np.arange(slices.cols) + 0.5) * pitch - slices.shift_mm[0] - patch.origin_x_mm
    ys = (slices.row0 + np.arange(slices.rows) + 0.5) * pitch - slices.shift_mm[1] - patch.origin_y_mm
    inside_x = np.nonzero((xs > pitch) & (xs < patch.width_mm - pitch))[0]
    inside_y = np.nonzero((ys > pitch) & (ys < patch.depth_mm - pitch))[0]
    yy, xx = np.meshgrid(ys[inside_y], xs[inside_x], indexing="ij")
    designed = interpolate(np.column_stack([yy.ravel(), xx.ravel()])).reshape(yy.shape)
    cases.append(("designed relief (printer pixels, no layers)", designed, pitch))
    rows = slice(inside_y[0], inside_y[-1] + 1)
    cols = slice(inside_x[0], inside_x[-1] + 1)
    for sigma in (0.0, nominal, 2.0 * nominal):
        h = printed_heights(slices, cure, sigma)[rows, cols]
        cases.append((f"as printed, pixel centres, spread {sigma * 1000:.0f} um", h, pitch))
    for sigma in (0.0, nominal, 2.0 * nominal):
        h = printed_heights(slices, cure, sigma, oversample=3)[3 * edge : -3 * edge, 3 * edge : -3 * edge]
        cases.append((f"as printed, 3 x 3 per pixel, spread {sigma * 1000:.0f} um", h, pitch / 3.0))
    maps = []
    for label, h, p in cases:
        energy, facets, f = axis_shares(h, p)
        maps.append((label, f))
        print(f"{label:48s} energy near the axes {energy:.3f}  facets near the axes {facets:.3f}", flush=True)
    energy86, _, _ = axis_shares(cases[1][1], pitch, n_phi=86)
    print(f"{cases[1][0]} with 86 azimuth bins (axes off the bin edges): energy near the axes {energy86:.3f}")
    if args.figure:
        _figure(maps, args.figure)


def _figure(maps: list[tuple[str, np.ndarray]], path: str) -> None:
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    theta = np.linspace(0.0, 90.0, 46)
    phi = np.radians(np.linspace(0.0, 360.0, 91))
    positive = np.concatenate([f[f > 0] for _, f in maps])
    norm = LogNorm(vmin=float(np.percentile(positive, 2)), vmax=float(np.percentile(positive, 99.5)))
    fig = Figure(figsize=(2.6 * len(maps), 4.0), dpi=80, layout="constrained")
    mesh = None
    for i, (label, f) in enumerate(maps):
        ax = fig.add_subplot(1, len(maps), i + 1, projection="polar")
        mesh = ax.pcolormesh(phi, theta, np.clip(f, norm.vmin, None), norm=norm, cmap="magma", shading="flat")
        ax.set_ylim(0.0, 90.0)
        ax.set_yticks([30, 60, 90])
        ax.set_yticklabels([])
        ax.set_xticks(np.radians([0, 90, 180, 270]))
        ax.tick_params(labelsize=7)
        ax.set_title(label.replace(", spread", "\nspread").replace(" (", "\n("), fontsize=8)
    fig.colorbar(
        mesh,
        ax=fig.axes,
        location="bottom",
        shrink=0.5,
        label="surface-reflection BRDF (1/sr), light from the zenith, demo tile, 1e6 rays",
    )
    fig.savefig(path, metadata={"Software": None})


if __name__ == "__main__":
    main()
