"""Slicing for resin printers: printer profiles (layer images and .sl1 come later).

Pure numerics and data; no printing.
"""

from slicing.printers import PRINTERS, PrinterProfile, custom_printer

__all__ = ["PRINTERS", "PrinterProfile", "custom_printer"]
