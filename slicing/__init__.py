"""Slicing for resin printers: printer profiles, layer images with exact area coverage, .sl1 archives.

Pure numerics; the .sl1 writer writes to a stream its caller opens. No printing.
"""

from slicing.layers import Slices, slice_heightfield, slice_mesh
from slicing.printers import PRINTERS, PrinterProfile, UnknownPrinterError, custom_printer, find_printer
from slicing.raster import rasterise_sections, section_segments, slice_heights
from slicing.sl1 import encode_png_grey, read_sl1, write_sl1

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
