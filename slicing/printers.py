"""Resin printer profiles: display geometry, layer heights and exposure.

The profiles ship as ``printers.toml`` beside this module (data, not code). A
"custom" profile is built from a pitch, a resolution and a layer height.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources


@dataclass(frozen=True)
class PrinterProfile:
    """A masked-SLA / DLP printer: what it can expose and how thin it can cure.

    Lengths in mm, times in seconds.
    """

    name: str
    label: str
    display_width_mm: float
    display_height_mm: float
    display_pixels_x: int
    display_pixels_y: int
    orientation: str
    mirror_x: bool
    mirror_y: bool
    max_print_height_mm: float
    layer_height_mm: float
    initial_layer_height_mm: float
    min_layer_height_mm: float
    max_layer_height_mm: float
    exposure_s: float
    initial_exposure_s: float
    antialiasing: bool

    @property
    def pitch_x_mm(self) -> float:
        """Pixel pitch along the display's x axis (mm)."""
        return self.display_width_mm / self.display_pixels_x

    @property
    def pitch_y_mm(self) -> float:
        """Pixel pitch along the display's y axis (mm)."""
        return self.display_height_mm / self.display_pixels_y

    @property
    def pitch_mm(self) -> float:
        """The coarser of the two pixel pitches (mm): the finest detail printable in both directions."""
        return max(self.pitch_x_mm, self.pitch_y_mm)

    def layer_count(self, height_mm: float, layer_height_mm: float | None = None) -> int:
        """Number of layers for a part ``height_mm`` tall (:func:`slicing.raster.layer_count`)."""
        from slicing.raster import layer_count

        lh = self.layer_height_mm if layer_height_mm is None else layer_height_mm
        return layer_count(height_mm, lh, self.initial_layer_height_mm)


def _load_profiles() -> dict[str, PrinterProfile]:
    text = resources.files("slicing").joinpath("printers.toml").read_text(encoding="utf-8")
    table = tomllib.loads(text)
    return {name: PrinterProfile(name=name, **values) for name, values in table.items()}


PRINTERS: dict[str, PrinterProfile] = _load_profiles()


class UnknownPrinterError(KeyError, ValueError):
    """A printer name that no profile has; the message names the known ones."""

    def __str__(self) -> str:
        return str(self.args[0])


def find_printer(name: str) -> PrinterProfile:
    """The profile called ``name``.

    Raises
    ------
    UnknownPrinterError
        With a sentence listing the known profiles and the closest name, if any.
    """
    if name in PRINTERS:
        return PRINTERS[name]
    import difflib

    close = difflib.get_close_matches(name, PRINTERS, n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise UnknownPrinterError(
        f"unknown printer '{name}', expected one of {', '.join(sorted(PRINTERS))}{hint}"
    )


def custom_printer(pitch_mm: float, pixels_x: int, pixels_y: int, layer_height_mm: float) -> PrinterProfile:
    """A square-pixel printer from its pitch (mm), resolution (px) and layer height (mm)."""
    if not (pitch_mm > 0 and pixels_x > 0 and pixels_y > 0 and layer_height_mm > 0):
        raise ValueError("custom printer: pitch, resolution and layer height must all be positive")
    return PrinterProfile(
        name="custom",
        label=f"custom {pixels_x}x{pixels_y} px at {pitch_mm * 1000:g} um",
        display_width_mm=pitch_mm * pixels_x,
        display_height_mm=pitch_mm * pixels_y,
        display_pixels_x=pixels_x,
        display_pixels_y=pixels_y,
        orientation="landscape",
        mirror_x=False,
        mirror_y=False,
        max_print_height_mm=150.0,
        layer_height_mm=layer_height_mm,
        initial_layer_height_mm=layer_height_mm,
        min_layer_height_mm=layer_height_mm,
        max_layer_height_mm=layer_height_mm,
        exposure_s=2.0,
        initial_exposure_s=20.0,
        antialiasing=True,
    )
