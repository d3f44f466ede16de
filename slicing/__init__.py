"""Slicing for resin printers: printer profiles, layer images with exact area coverage, .sl1 archives.

Pure numerics; the .sl1 writer writes to a stream its caller opens. No printing.
"""

from noise.lazy import lazy_package

# Names resolve on first use: `find_printer` (emboss, design checks) needs no numba.
lazy_package(
    __name__,
    {
        "Slices": "slicing.layers",
        "slice_heightfield": "slicing.layers",
        "slice_mesh": "slicing.layers",
        "PRINTERS": "slicing.printers",
        "PrinterProfile": "slicing.printers",
        "UnknownPrinterError": "slicing.printers",
        "custom_printer": "slicing.printers",
        "find_printer": "slicing.printers",
        "rasterise_sections": "slicing.raster",
        "section_segments": "slicing.raster",
        "slice_heights": "slicing.raster",
        "encode_png_grey": "slicing.sl1",
        "read_sl1": "slicing.sl1",
        "write_sl1": "slicing.sl1",
    },
)

__all__ = [
    "PRINTERS",
    "PrinterProfile",
    "Slices",
    "UnknownPrinterError",
    "custom_printer",
    "encode_png_grey",
    "find_printer",
    "rasterise_sections",
    "read_sl1",
    "section_segments",
    "slice_heightfield",
    "slice_heights",
    "slice_mesh",
    "write_sl1",
]
