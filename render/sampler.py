"""Padded (0, 2)-sequences with every dimension scrambled on its own: the preview's sampler.

Kollig and Keller's padding ("Efficient multidimensional sampling", 2002), which Mitsuba's
``ldsampler`` follows: the ``spp`` samples of a pixel take, in each 1-D or 2-D dimension the
path asks for, the first ``spp`` points of the van der Corput sequence (1-D) or of Sobol's
(0, 2)-sequence (2-D), randomised by an XOR scramble of their digits (a random digital shift:
each point stays uniform, the set stays stratified), and the dimensions are decorrelated by
shuffling the sample index differently in each (Kensler's hashed permutation, "Correlated
Multi-Jittered Sampling", Pixar 2013).

Unlike ``ldsampler``, every dimension's shuffle and both of its scrambles are hashed from the
pixel and the dimension (TEA, :func:`mitsuba.sample_tea_32`). ``ldsampler`` XORs every 1-D
dimension of a pixel with one scramble word and every 2-D dimension with one pair, so the
bits below the stratum are the same in every dimension of a sample: the lobe chosen at one
bounce is tied to the lobe and the direction at the next, and the image moved by 1.25 %
(60 standard errors) with the coat's mirror probability, a sampling parameter
(docs/benchmarks.md, sixteenth and seventeenth runs). Here the V-groove tile agrees with the
independent sampler and with Mitsuba's own film loop (tests/test_progressive_sampler.py),
and the variance is ``ldsampler``'s: in ``printapp bench scale`` the compact model needs 23
samples for 2 % where ``multijitter`` needs 37, the geometry 52 where it needs 65; on the CAD
previews (printapp's own path loop, :mod:`render.caustics`) it is ``multijitter``'s.

A Python ``mi.Sampler``: its state is a ``DRJIT_STRUCT`` so that Dr.Jit's symbolic loops
carry it. They rebuild the sampler from its default constructor and set those fields alone,
so everything the samples depend on, the sample count included, is a field.
"""

from __future__ import annotations

from typing import Any

NAME = "printapp_padded"
"""The plugin's name, for ``mi.load_dict({"type": NAME, "sample_count": spp})``."""

_registered: set[str] = set()


def permute_pow2(index: Any, low_bits: Any, seed: Any) -> Any:
    """Kensler's hashed permutation of ``[0, n)`` for ``n`` a power of two, ``low_bits = n - 1``.

    Every step is a bijection on the low bits, so the rejection loop of the general case is
    never taken and the permutation is one expression (it equals ``mi.permute_kensler`` for
    these lengths: tests/test_progressive_sampler.py).
    """
    import mitsuba as mi

    w = mi.UInt32(low_bits)
    p = mi.UInt32(seed)
    i = mi.UInt32(index) ^ p
    i *= 0xE170893D
    i ^= p >> 16
    i ^= (i & w) >> 4
    i ^= p >> 8
    i *= 0x0929EB3F
    i ^= p >> 23
    i ^= (i & w) >> 1
    i *= 1 | (p >> 27)
    i *= 0x6935FA69
    i ^= (i & w) >> 11
    i *= 0x74DCB303
    i ^= (i & w) >> 2
    i *= 0x9E501CC3
    i ^= (i & w) >> 2
    i *= 0xC860A3DF
    i &= w
    i ^= i >> 5
    return (i + p) & w


def register() -> str:
    """Register the sampler with Mitsuba for the current variant (once); returns :data:`NAME`."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _registered:
        return NAME

    class PaddedSampler(mi.Sampler):
        DRJIT_STRUCT = {"key": mi.UInt32, "index": mi.UInt32, "dim": mi.UInt32, "low": mi.UInt32}

        def __init__(self, props: Any = None) -> None:
            super().__init__(props if props is not None else mi.Properties())
            self.key = mi.UInt32(0)  # per lane: the hash of the seed and the lane's pixel
            self.index = mi.UInt32(0)  # per lane: the sample's index within its pixel
            self.dim = mi.UInt32(0)  # per lane: the next dimension
            self.low = mi.UInt32(0)  # the sample count less one (a power of two)

        def seed(self, seed: int, wavefront_size: int = 1) -> None:
            spp = int(self.sample_count())
            if spp < 1 or spp & (spp - 1):
                raise ValueError(f"sample_count: expected a power of two, got {spp}")
            lane = dr.arange(mi.UInt32, wavefront_size)
            # The seed held opaque: as a literal, every pass's seed would compile a kernel.
            self.key = mi.sample_tea_32(dr.opaque(mi.UInt32, int(seed) & 0xFFFFFFFF), lane // spp, 4)[0]
            self.index = lane % spp
            self.low = mi.UInt32(spp - 1)
            self.dim = dr.zeros(mi.UInt32, wavefront_size)

        def _next(self) -> tuple[Any, Any, Any]:
            d = self.dim
            self.dim = d + 1
            shuffle, word = mi.sample_tea_32(self.key, d, 4)
            scramble_x, scramble_y = mi.sample_tea_32(word, shuffle, 2)
            return permute_pow2(self.index, self.low, shuffle), scramble_x, scramble_y

        def next_1d(self, active: Any = True) -> Any:
            i, scramble, _ = self._next()
            return mi.radical_inverse_2(i, scramble)

        def next_2d(self, active: Any = True) -> Any:
            i, scramble_x, scramble_y = self._next()
            return mi.Point2f(mi.radical_inverse_2(i, scramble_x), mi.sobol_2(i, scramble_y))

        def clone(self) -> Any:
            props = mi.Properties()
            props["sample_count"] = int(self.sample_count())
            out = PaddedSampler(props)
            out.key, out.index, out.dim, out.low = self.key, self.index, self.dim, self.low
            return out

        def fork(self) -> Any:
            return self.clone()

        def schedule_state(self) -> None:
            dr.schedule(self.key, self.index, self.dim, self.low)

    mi.register_sampler(NAME, lambda props: PaddedSampler(props))
    _registered.add(variant)
    return NAME
