"""The SL1 layers' own deflate encoder (slicing.deflate), checked by zlib's and Pillow's decoders."""

import dataclasses
import heapq
import io
import zlib

import numpy as np
import pytest
import trimesh
from PIL import Image

from slicing import PRINTERS, slice_mesh
from slicing.deflate import _huffman_lengths, deflate_runs
from slicing.sl1 import _display_png, encode_display_png

SL1 = PRINTERS["prusa-sl1"]


def inflate(stream: bytes) -> bytes:
    return zlib.decompressobj(-15).decompress(stream)


def assert_runs_round_trip(values, lengths) -> bytes:
    stream, adler = deflate_runs(np.asarray(values), np.asarray(lengths))
    want = np.repeat(np.asarray(values, dtype=np.uint8), lengths).tobytes()
    assert inflate(stream) == want
    assert adler == zlib.adler32(want)
    assert stream.endswith(b"\x00\x00\xff\xff")  # a full flush: the next piece starts on a byte
    return stream


@pytest.mark.parametrize("length", [1, 2, 3, 4, 5, 257, 258, 259, 260, 261, 262, 516, 517, 100_000])
def test_runs_of_every_awkward_length(length):
    """Matches run 3-258 bytes, so a run's tail of one or two must not be left to a match."""
    assert_runs_round_trip([0, 255, 7], [length, length, 1])


def test_random_runs_round_trip():
    rng = np.random.default_rng(20)
    for _ in range(20):
        n = int(rng.integers(1, 3000))
        palette = rng.integers(0, 256, size=int(rng.integers(1, 20)))
        values = rng.choice(palette, n)
        lengths = rng.geometric(10.0 ** -rng.uniform(0, 3), n)
        assert_runs_round_trip(values, lengths)


def test_a_code_longer_than_fifteen_bits_is_limited():
    """Fibonacci counts make Huffman's code 25 bits deep; deflate allows 15."""
    counts = [1, 1]
    while len(counts) < 26:
        counts.append(counts[-1] + counts[-2])
    values = np.repeat(np.arange(26), counts)
    np.random.default_rng(3).shuffle(values)
    assert_runs_round_trip(values, np.ones(values.size, dtype=int))


def test_every_byte_value_and_the_fixed_code():
    assert_runs_round_trip(np.arange(256), np.full(256, 300))
    # One byte: the fixed code's block is shorter than any header, and is taken.
    stream = assert_runs_round_trip([200], [1])
    assert (stream[0] >> 1) & 3 == 1


def test_pieces_splice_into_one_zlib_stream():
    rng = np.random.default_rng(5)
    parts, want, adler = [], b"", 1
    for _ in range(4):
        values, lengths = rng.integers(0, 256, 50), rng.integers(1, 600, 50)
        parts.append(deflate_runs(values, lengths)[0])
        chunk = np.repeat(values.astype(np.uint8), lengths).tobytes()
        want += chunk
        adler = zlib.adler32(chunk, adler)
    stream = b"\x78\x01" + b"".join(parts) + b"\x03\x00" + adler.to_bytes(4, "big")
    assert zlib.decompress(stream) == want


def _reference_huffman_cost(freq: np.ndarray) -> int:
    """Total bits of an optimal prefix code (Huffman's merge with a heap), unlimited depth."""
    heap = [int(f) for f in freq if f > 0]
    heapq.heapify(heap)
    cost = 0
    while len(heap) > 1:
        merged = heapq.heappop(heap) + heapq.heappop(heap)
        cost += merged
        heapq.heappush(heap, merged)
    return cost


def test_huffman_lengths_are_complete_and_optimal():
    rng = np.random.default_rng(11)
    for _ in range(50):
        freq = np.where(rng.random(286) < 0.3, rng.geometric(0.01, 286), 0).astype(np.int64)
        freq[int(rng.integers(0, 286))] += 1
        freq[int(rng.integers(0, 286))] += 1
        if np.count_nonzero(freq) < 2:
            continue
        lengths = _huffman_lengths(freq, np.int64(15))
        used = freq > 0
        assert np.all((lengths > 0) == used)
        assert np.sum(2.0 ** -lengths[used]) == pytest.approx(1.0)  # Kraft: a complete code
        if lengths.max() < 15:
            assert int(np.sum(freq * lengths)) == _reference_huffman_cost(freq)
    limited = _huffman_lengths(np.array([2**k for k in range(19)], dtype=np.int64), np.int64(7))
    assert limited.max() <= 7 and np.sum(2.0**-limited) == pytest.approx(1.0)


def test_bad_runs():
    with pytest.raises(ValueError, match="runs: expected byte values"):
        deflate_runs(np.array([256]), np.array([1]))
    with pytest.raises(ValueError, match="same 1-D shape"):
        deflate_runs(np.array([1, 2]), np.array([1]))


def _png_pixels(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)))


@pytest.mark.parametrize("orientation", ["portrait", "landscape"])
@pytest.mark.parametrize("mirror_x", [False, True])
@pytest.mark.parametrize("mirror_y", [False, True])
def test_layers_deflated_while_rasterised_match_the_image_path(orientation, mirror_x, mirror_y):
    """Every layer of an off-centre cone, on every display orientation and mirroring, decoded by
    Pillow: the same pixels as rasterising an image, turning it and deflating it with zlib-ng."""
    printer = dataclasses.replace(SL1, orientation=orientation, mirror_x=mirror_x, mirror_y=mirror_y)
    cone = trimesh.creation.cone(radius=3.0, height=1.0, sections=24)
    cone.apply_translation((3.3, 1.1, 0.2))
    slices = slice_mesh(cone.vertices, cone.faces, printer)
    shape = slices.display_shape()
    scratch, scratch_image = {}, {}
    cured = 0
    for k in range(slices.n_layers):
        part, adler, row0, height = slices.deflate_display_rows(k, scratch)
        ours = _png_pixels(_display_png(shape, row0, height, part, adler))
        block, r0, c0 = slices.display_block(*slices.layer_grey(k, scratch_image))
        image = _png_pixels(encode_display_png(np.ascontiguousarray(block), r0, c0, shape))
        np.testing.assert_array_equal(ours, image)
        cured += int(np.count_nonzero(ours == 255))
    assert cured > 1000
