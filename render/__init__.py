"""Appearance of printed microgeometry: microfacet statistics and Mitsuba 3 renders.

Mitsuba is imported lazily inside :mod:`render.mitsuba_adapter`'s functions.
"""

from render.microfacet import SlopeRoughness, slope_roughness

__all__ = ["SlopeRoughness", "slope_roughness"]
