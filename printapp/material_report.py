"""What ``printapp material`` shows: a material's optics as a report, a plot, and its options parsed."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from printapp.materials import MaterialError, find_material, resolve_parameters, spectral_optics


def material_report(
    name_or_file: str, parameters: dict[str, float] | None = None, wavelengths_nm: list[float] | None = None
) -> tuple[dict[str, Any], Any]:
    """Everything ``printapp material`` prints, as a JSON-ready dict, and the spectral optics."""
    from render.translucency import appearance_from_spectra

    spec, library = find_material(name_or_file)
    values = resolve_parameters(spec, parameters)
    optics = spectral_optics(
        spec, library, values, None if wavelengths_nm is None else np.asarray(wavelengths_nm)
    )
    look = appearance_from_spectra(
        optics.wavelength_nm, optics.host_index, optics.sigma_s_per_mm, optics.sigma_a_per_mm, optics.g
    )
    index_names = [spec.host] + [str(p.get("index")) for p in spec.particles]
    index_names += [spec.options[k] for k in ("fat_index", "casein_index") if k in spec.options]
    raw_indices = getattr(library, "_raw_indices", {})
    expanded: list[str] = []
    while index_names:
        name = index_names.pop(0)
        if name not in expanded:
            expanded.append(name)
            index_names.extend(raw_indices.get(name, {}).get("of", []))
    sources = list(spec.sources) + [
        library.index_sources[n] for n in expanded if library.index_sources.get(n)
    ]
    if "absorber" in spec.options:
        sources.append(library.absorbers[spec.options["absorber"]]["source"])

    def listed(values: np.ndarray, digits: int = 6) -> list[float]:
        return [float(f"{v:.{digits}g}") for v in np.asarray(values, dtype=np.float64)]

    report = {
        "material": spec.name,
        "description": spec.description,
        "parameters": values,
        "units": "coefficients in 1/mm, lengths in mm, wavelengths in nm (vacuum)",
        "spectral": {
            "wavelength_nm": listed(optics.wavelength_nm),
            "host_n": listed(optics.host_index.real),
            "host_kappa": listed(-optics.host_index.imag),
            "sigma_s_per_mm": listed(optics.sigma_s_per_mm),
            "sigma_a_per_mm": listed(optics.sigma_a_per_mm),
            "sigma_t_per_mm": listed(optics.sigma_t_per_mm),
            "g": listed(optics.g),
            "reduced_scattering_per_mm": listed(optics.reduced_scattering_per_mm),
            "transport_mfp_mm": listed(optics.transport_mfp_mm),
        },
        "components": {
            name: {key: listed(value) for key, value in parts.items()}
            for name, parts in optics.components.items()
        },
        "rgb": {
            "sigma_s_per_mm": listed(look.medium.sigma_s_per_mm),
            "sigma_a_per_mm": listed(look.medium.sigma_a_per_mm),
            "g": float(f"{look.medium.g:.6g}"),
            "transport_mfp_mm": [
                float(f"{v:.6g}") if math.isfinite(v) else None for v in look.transport_mfp_mm
            ],
            "body_albedo": listed(look.body_albedo),
            "refractive_index": float(f"{look.refractive_index:.6g}"),
        },
        "sources": sources,
    }
    return report, optics


def material_plot_png(report: dict[str, Any], optics: Any) -> bytes:
    """Spectra (sigma_s, sigma_s', sigma_a) and the ensemble phase function at three wavelengths."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lam = optics.wavelength_nm
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), dpi=110)
    ax = axes[0]
    ax.semilogy(lam, optics.sigma_s_per_mm, "o-", label="sigma_s")
    ax.semilogy(lam, optics.reduced_scattering_per_mm, "s--", label="sigma_s' = sigma_s (1 - g)")
    if np.any(optics.sigma_a_per_mm > 0):
        ax.semilogy(lam, np.clip(optics.sigma_a_per_mm, 1e-12, None), "^-", label="sigma_a")
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("coefficient (1/mm)")
    ax2 = ax.twinx()
    ax2.plot(lam, optics.g, "k:", label="g")
    ax2.set_ylabel("asymmetry g")
    ax2.set_ylim(-0.05, 1.0)
    lines = ax.get_legend_handles_labels()
    more = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + more[0], lines[1] + more[1], fontsize=8, loc="lower left")
    ax.set_title(f"{report['material']}: scattering properties")
    theta = np.linspace(0.0, 180.0, 721)
    mu = np.cos(np.radians(theta))
    picks = sorted({int(np.argmin(np.abs(lam - target))) for target in (450.0, 550.0, 650.0)})
    for k in picks:
        axes[1].semilogy(theta, optics.phase_function(mu, k), label=f"{lam[k]:g} nm, g = {optics.g[k]:.3f}")
    axes[1].set_xlabel("scattering angle (degrees)")
    axes[1].set_ylabel("phase function p (1/sr)")
    axes[1].set_title("ensemble phase function (Lorenz-Mie)")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return buffer.getvalue()


def parse_parameters(items: list[str]) -> dict[str, float]:
    """``--param NAME=VALUE`` options as a dict of finite numbers.

    Raises
    ------
    MaterialError
        For an item that is not NAME=VALUE with a finite number.
    """
    values: dict[str, float] = {}
    for item in items:
        key, sep, text = item.partition("=")
        try:
            number = float(text)
        except ValueError:
            number = math.nan
        if not sep or not key or not math.isfinite(number):
            raise MaterialError(f"--param: expected NAME=VALUE with a finite number, got '{item}'")
        values[key.strip()] = number
    return values


def parse_wavelengths(text: str | None) -> list[float] | None:
    """``--wavelengths-nm L1,L2,...``: increasing positive wavelengths (nm), or None for the material's own.

    Raises
    ------
    MaterialError
        For anything else.
    """
    if text is None:
        return None
    try:
        lam = [float(v) for v in text.split(",")]
    except ValueError:
        raise MaterialError(f"--wavelengths-nm: expected comma-separated numbers, got '{text}'") from None
    increasing = all(b > a for a, b in zip(lam, lam[1:], strict=False))
    if not increasing or any(not (math.isfinite(v) and v > 0) for v in lam):
        raise MaterialError(f"--wavelengths-nm: expected increasing positive wavelengths, got '{text}'")
    return lam
