"""``printapp material``: a material's scattering properties from its particles (Lorenz-Mie)."""

import json
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table

from printapp.cli.app import QuietOption, app, out, working
from printapp.errors import PrintappError


def _triple(values: list[Any], fmt: str) -> str:
    return ", ".join("inf" if v is None else format(v, fmt) for v in values)


def _print_report(report: dict[str, Any]) -> None:
    spectral = report["spectral"]
    table = Table(
        "wavelength nm",
        "host n",
        "sigma_s 1/mm",
        "sigma_a 1/mm",
        "sigma_t 1/mm",
        "g",
        "sigma_s' 1/mm",
        "transport mfp mm",
        title=f"{report['material']}: {report['description']}",
    )
    for k, lam_k in enumerate(spectral["wavelength_nm"]):
        table.add_row(
            f"{lam_k:g}",
            f"{spectral['host_n'][k]:.4f}",
            f"{spectral['sigma_s_per_mm'][k]:.5g}",
            f"{spectral['sigma_a_per_mm'][k]:.4g}",
            f"{spectral['sigma_t_per_mm'][k]:.5g}",
            f"{spectral['g'][k]:.4f}",
            f"{spectral['reduced_scattering_per_mm'][k]:.5g}",
            f"{spectral['transport_mfp_mm'][k]:.4g}",
        )
    out.print(table)
    rgb = report["rgb"]
    parameters = ", ".join(f"{k} = {v:g}" for k, v in report["parameters"].items()) or "none"
    out.print(f"parameters: {parameters}")
    out.print(
        f"linear RGB: sigma_s ({_triple(rgb['sigma_s_per_mm'], '.5g')}) 1/mm, "
        f"sigma_a ({_triple(rgb['sigma_a_per_mm'], '.4g')}) 1/mm, g {rgb['g']:.4f}, "
        f"transport mfp ({_triple(rgb['transport_mfp_mm'], '.4g')}) mm"
    )
    out.print(
        f"body albedo ({_triple(rgb['body_albedo'], '.4f')}), refractive index {rgb['refractive_index']:.4f}"
    )
    for source in report["sources"]:
        out.print(f"source: {source}")


@app.command("material")
def material_command(
    material: Annotated[
        str, typer.Argument(help="A catalogue material (white-resin, milk, ...) or a material .toml file.")
    ],
    param: Annotated[
        list[str] | None, typer.Option("--param", "-p", help="Set a parameter, NAME=VALUE (repeatable).")
    ] = None,
    wavelengths_nm: Annotated[
        str | None, typer.Option(help="Comma-separated wavelengths (nm) [the material's own samples].")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of tables.")] = False,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write spectra and phase functions to this PNG.")
    ] = None,
    quiet: QuietOption = False,
) -> None:
    """Optical properties of a material from its particles (Lorenz-Mie): sigma_s, sigma_a, g, in RGB too."""
    from printapp.material_report import (
        material_plot_png,
        material_report,
        parse_parameters,
        parse_wavelengths,
    )
    from printapp.outputs import atomic_write_bytes

    values = parse_parameters(param or [])
    lam = parse_wavelengths(wavelengths_nm)
    if plot is not None and plot.suffix.lower() != ".png":
        raise PrintappError(f"{plot}: expected a plot file ending in .png")
    with working("Lorenz-Mie optics", quiet or as_json):
        report, optics = material_report(material, values, lam)
    if plot is not None:
        atomic_write_bytes(plot, material_plot_png(report, optics))
    if as_json:
        typer.echo(json.dumps(report, indent=2))
        return
    _print_report(report)
    if plot is not None:
        out.print(f"wrote {plot}")
