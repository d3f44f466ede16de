"""A layer's display rows rasterised straight into a deflate stream (RFC 1951), with no image.

A resin layer is long runs of dark (0) and cured (255) pixels with a few grey pixels where
the section's edges cross them, and the rasteriser already walks it run by run: between
two pixels that a segment touched, every pixel repeats the last grey. So the layer is
encoded as it is rasterised, each run as one literal and matches at distance 1, in one
deflate block with a Huffman code made for it (RFC 1951, 3.2.7; or the fixed code of
3.2.6 where that comes out shorter), ending on a full flush (an empty stored block:
``00 00 FF FF``) so that it can be spliced between other deflate pieces. The adler-32 of
the bytes (RFC 1950, 2.2) is summed run by run in closed form.

Beside the image path (rasterise to grey, turn the block to the display's orientation,
copy it into PNG scanlines, deflate them, sum them) this skips three passes over every
pixel; for the portrait displays of Prusa's printers the turn is a transpose, which the
rasteriser avoids by rasterising in the display's orientation (x and y swapped).

Pure numerics; no file I/O.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from slicing.raster import BLOCK_SHIFT, _add_segments, _grey_level, mark_blocks

_ADLER_MOD = 65521
_END_OF_BLOCK = 256
_MATCH = 256
"""An item above this is a match of (item - 256) bytes at distance 1; below it, a literal byte.
Items fit int16 (at most 514): two bytes a pixel in the worst case, every pixel a literal."""
_STATE_BITS, _STATE_COUNT, _STATE_POS = range(3)
_CODE_LENGTH_ORDER = np.array([16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15])


def _length_codes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a match of 3-258 bytes: its length symbol, its extra bits' count and value (RFC 1951, 3.2.5)."""
    bases = [3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115]
    bases += [131, 163, 195, 227, 258]
    extra = [0] * 8 + [1] * 4 + [2] * 4 + [3] * 4 + [4] * 4 + [5] * 4 + [0]
    symbol = np.zeros(259, dtype=np.int64)
    n_extra = np.zeros(259, dtype=np.int64)
    value = np.zeros(259, dtype=np.uint64)
    # In order, so that symbol 285 (exactly 258 bytes) overwrites the 258 that 284's extra bits could name.
    for index, (base, bits) in enumerate(zip(bases, extra, strict=True)):
        for length in range(base, min(base + (1 << bits) - 1, 258) + 1):
            symbol[length], n_extra[length], value[length] = 257 + index, bits, length - base
    return symbol, n_extra, value


_LENGTH_SYMBOL, _LENGTH_EXTRA_BITS, _LENGTH_EXTRA_VALUE = _length_codes()
_SYMBOL_EXTRA_BITS = np.zeros(286, dtype=np.int64)
_SYMBOL_EXTRA_BITS[_LENGTH_SYMBOL[3:]] = _LENGTH_EXTRA_BITS[3:]
_FIXED_LENGTHS = np.array([8] * 144 + [9] * 112 + [7] * 24 + [8] * 8, dtype=np.int64)
"""The fixed literal/length code's lengths, all 288 (RFC 1951, 3.2.6): its codes are their canonical codes."""


@njit(cache=True, nogil=True)
def _put(state, out, bits, n_bits) -> None:
    """Append ``n_bits`` bits (least significant first) to the stream in ``out``."""
    buffer = state[_STATE_BITS] | (np.uint64(bits) << state[_STATE_COUNT])
    count = state[_STATE_COUNT] + np.uint64(n_bits)
    pos = state[_STATE_POS]
    while count >= 8:
        out[pos] = buffer & np.uint64(0xFF)
        buffer >>= np.uint64(8)
        count -= np.uint64(8)
        pos += np.uint64(1)
    state[_STATE_BITS], state[_STATE_COUNT], state[_STATE_POS] = buffer, count, pos


@njit(cache=True, nogil=True)
def _push_run(items, n_items: int, freq, value: int, length: int) -> int:
    """``length`` copies of byte ``value`` as items: a literal, then matches at distance 1."""
    items[n_items] = value
    freq[value] += 1
    n_items += 1
    rest = length - 1
    while rest >= 3:
        take = min(rest, 258)
        if rest - take == 1 or rest - take == 2:
            take -= 3  # a match is at least three bytes long: leave four or five
        items[n_items] = _MATCH + take
        freq[_LENGTH_SYMBOL[take]] += 1
        n_items += 1
        rest -= take
    for _ in range(rest):
        items[n_items] = value
        freq[value] += 1
        n_items += 1
    return n_items


@njit(cache=True, nogil=True)
def _huffman_lengths(freq, max_bits: int):
    """Code lengths of a Huffman code for ``freq``, none longer than ``max_bits`` (RFC 1951, 3.2.2).

    Huffman's construction (two queues over the weights, sorted stably); while a code comes
    out too long, the weights are halved (rounding up, so no used symbol drops out) and it
    is built again. A lone used symbol gets a partner, as decoders require complete codes.
    """
    n = freq.size
    lengths = np.zeros(n, dtype=np.int64)
    order = np.empty(n, dtype=np.int64)
    m = 0
    for symbol in range(n):
        if freq[symbol] > 0:
            order[m] = symbol
            m += 1
    if m == 0:
        return lengths
    if m == 1:
        lengths[order[0]] = 1
        lengths[1 if order[0] == 0 else 0] = 1
        return lengths
    w = np.empty(2 * m - 1, dtype=np.int64)
    parent = np.empty(2 * m - 1, dtype=np.int64)
    depth = np.empty(2 * m - 1, dtype=np.int64)
    scale = 0
    while True:
        # The used symbols by weight, ties by symbol (insertion sort: a few hundred at most).
        for i in range(m):
            symbol = order[i]
            weight = ((freq[symbol] - 1) >> scale) + 1
            j = i
            while j > 0 and w[j - 1] > weight:
                w[j] = w[j - 1]
                order[j] = order[j - 1]
                j -= 1
            w[j] = weight
            order[j] = symbol
        leaf, taken = 0, m
        for made in range(m, 2 * m - 1):
            total = 0
            for _ in range(2):
                if leaf < m and (taken >= made or w[leaf] <= w[taken]):
                    parent[leaf] = made
                    total += w[leaf]
                    leaf += 1
                else:
                    parent[taken] = made
                    total += w[taken]
                    taken += 1
            w[made] = total
        depth[2 * m - 2] = 0
        longest = 0
        for node in range(2 * m - 3, -1, -1):
            depth[node] = depth[parent[node]] + 1
            if node < m:
                longest = max(longest, depth[node])
        if longest <= max_bits:
            for i in range(m):
                lengths[order[i]] = depth[i]
            return lengths
        scale += 1


@njit(cache=True, nogil=True)
def _canonical_codes(lengths):
    """The canonical codes of ``lengths`` (RFC 1951, 3.2.2), bit-reversed for packing."""
    counts = np.zeros(16, dtype=np.int64)
    for n in lengths:
        counts[n] += 1
    counts[0] = 0
    next_code = np.zeros(16, dtype=np.int64)
    code = 0
    for bits in range(1, 16):
        code = (code + counts[bits - 1]) << 1
        next_code[bits] = code
    codes = np.zeros(lengths.size, dtype=np.uint64)
    for symbol in range(lengths.size):
        n = lengths[symbol]
        if n > 0:
            c = next_code[n]
            next_code[n] += 1
            reversed_code = 0
            for _ in range(n):
                reversed_code = (reversed_code << 1) | (c & 1)
                c >>= 1
            codes[symbol] = reversed_code
    return codes


@njit(cache=True, nogil=True)
def _write_block(items, n_items: int, freq, out) -> int:
    """Items (literals, matches at distance 1) as one deflate block ending on a full flush.

    The block takes a Huffman code of its own (BTYPE 10) or the fixed one (BTYPE 01),
    whichever is shorter with its header, as zlib does. Returns the bytes written.
    """
    freq[_END_OF_BLOCK] = 1
    lit_lengths = _huffman_lengths(freq, np.int64(15))
    n_lit = 257
    for symbol in range(257, 286):
        if lit_lengths[symbol] > 0:
            n_lit = symbol + 1
    # One distance is used (1); two codes of one bit keep the distance code complete.
    sequence = np.zeros(n_lit + 2, dtype=np.int64)
    sequence[:n_lit] = lit_lengths[:n_lit]
    sequence[n_lit:] = 1
    # The code lengths, run-length coded: 17 and 18 for runs of zeros, others as they are.
    cl_symbols = np.zeros(sequence.size, dtype=np.int64)
    cl_extra = np.zeros(sequence.size, dtype=np.int64)
    cl_freq = np.zeros(19, dtype=np.int64)
    n_cl = 0
    i = 0
    while i < sequence.size:
        run = 1
        if sequence[i] == 0:
            while i + run < sequence.size and sequence[i + run] == 0 and run < 138:
                run += 1
        if run >= 11:
            cl_symbols[n_cl], cl_extra[n_cl] = 18, run - 11
        elif run >= 3:
            cl_symbols[n_cl], cl_extra[n_cl] = 17, run - 3
        else:
            run = 1
            cl_symbols[n_cl] = sequence[i]
        cl_freq[cl_symbols[n_cl]] += 1
        n_cl += 1
        i += run
    cl_lengths = _huffman_lengths(cl_freq, np.int64(7))
    n_cl_lengths = 4
    for j in range(19):
        if cl_lengths[_CODE_LENGTH_ORDER[j]] > 0:
            n_cl_lengths = max(n_cl_lengths, j + 1)
    matches = 0
    extra_bits = 0
    for symbol in range(257, 286):
        matches += freq[symbol]
        extra_bits += freq[symbol] * _SYMBOL_EXTRA_BITS[symbol]
    dynamic_bits = 17 + 3 * n_cl_lengths + matches + extra_bits
    fixed_bits = 3 + 5 * matches + extra_bits
    for symbol in range(286):
        dynamic_bits += freq[symbol] * lit_lengths[symbol]
        fixed_bits += freq[symbol] * _FIXED_LENGTHS[symbol]
    for j in range(n_cl):
        s = cl_symbols[j]
        dynamic_bits += cl_lengths[s] + (7 if s == 18 else 3 if s == 17 else 0)

    state = np.zeros(3, dtype=np.uint64)
    if dynamic_bits < fixed_bits:
        _put(state, out, np.uint64(4), np.int64(3))  # BFINAL 0, BTYPE 10
        _put(state, out, np.uint64(n_lit - 257), np.int64(5))
        _put(state, out, np.uint64(1), np.int64(5))  # two distance codes
        _put(state, out, np.uint64(n_cl_lengths - 4), np.int64(4))
        for j in range(n_cl_lengths):
            _put(state, out, np.uint64(cl_lengths[_CODE_LENGTH_ORDER[j]]), np.int64(3))
        cl_codes = _canonical_codes(cl_lengths)
        for j in range(n_cl):
            s = cl_symbols[j]
            _put(state, out, np.uint64(cl_codes[s]), np.int64(cl_lengths[s]))
            if s == 18:
                _put(state, out, np.uint64(cl_extra[j]), np.int64(7))
            elif s == 17:
                _put(state, out, np.uint64(cl_extra[j]), np.int64(3))
        lengths = lit_lengths
        distance_bits = 1
    else:
        _put(state, out, np.uint64(2), np.int64(3))  # BFINAL 0, BTYPE 01
        lengths = _FIXED_LENGTHS.copy()
        distance_bits = 5
    codes = _canonical_codes(lengths)
    for t in range(n_items):
        item = items[t]
        if item < _MATCH:
            _put(state, out, np.uint64(codes[item]), np.int64(lengths[item]))
        else:
            take = item - _MATCH
            symbol = _LENGTH_SYMBOL[take]
            # The length's code and extra bits, then distance code 0 (distance 1), all zero bits.
            _put(
                state,
                out,
                np.uint64(codes[symbol] | (_LENGTH_EXTRA_VALUE[take] << np.uint64(lengths[symbol]))),
                np.int64(lengths[symbol] + _LENGTH_EXTRA_BITS[take] + distance_bits),
            )
    _put(state, out, np.uint64(codes[_END_OF_BLOCK]), np.int64(lengths[_END_OF_BLOCK]))
    # An empty stored block (BFINAL 0, BTYPE 00), padded to a byte: a full flush.
    _put(state, out, np.uint64(0), np.int64(3))
    if state[_STATE_COUNT] > 0:
        _put(state, out, np.uint64(0), np.int64(8 - int(state[_STATE_COUNT])))
    _put(state, out, np.uint64(0xFFFF0000), np.int64(32))
    return int(state[_STATE_POS])


@njit(cache=True, nogil=True)
def _adler_run(a: int, b: int, value: int, length: int) -> tuple[int, int]:
    """Adler-32's sums after ``length`` copies of byte ``value``: s1 += L v, s2 += L s1 + v L (L + 1) / 2."""
    b = (b + length * a + value * (length * (length + 1) // 2)) % _ADLER_MOD
    a = (a + length * value) % _ADLER_MOD
    return a, b


@njit(cache=True, nogil=True)
def _deflate_layer(
    seg,
    start,
    end,
    ox: float,
    oy: float,
    inv_pitch_x: float,
    inv_pitch_y: float,
    antialias: bool,
    whole,
    whole_marks,
    rows: int,
    cols: int,
    reverse_rows: bool,
    reverse_cols: bool,
    lead: int,
    row_bytes: int,
    items,
    out,
):
    """Rasterise segments start..end-1 on a ``rows`` x ``cols`` window and deflate its PNG scanlines.

    Each window row is one scanline of ``row_bytes`` bytes: the filter byte (0), ``lead``
    dark pixels, the row's pixels (right to left if ``reverse_cols``), dark pixels to the
    end; the scanlines go bottom row first if ``reverse_rows``. ``whole`` is the
    accumulator (at least rows x cols + 2, zero on entry, left zero), ``whole_marks`` its
    blocks' marks (at least rows x :func:`slicing.raster.mark_blocks` (cols), zero on entry, left zero);
    ``items`` holds at least rows x row_bytes items. Returns the bytes written to ``out``
    and the adler-32 of the scanlines. Pixels as :func:`slicing.raster._rasterise_layer_grey`.

    Only the blocks of a row that a segment wrote are read: elsewhere the accumulator is
    zero and every pixel repeats the last grey, and reading it (8 bytes a pixel) was most
    of the time.
    """
    acc = whole[:rows, : cols + 2]
    marks = whole_marks[:rows, : mark_blocks(cols)]
    _add_segments(seg, start, end, ox, oy, inv_pitch_x, inv_pitch_y, acc, marks)
    freq = np.zeros(286, dtype=np.int64)
    run_values = np.empty(cols + 1, dtype=np.int64)
    run_lengths = np.empty(cols + 1, dtype=np.int64)
    n_items = 0
    adler_a, adler_b = 1, 0
    value = 0
    length = 0
    trail = row_bytes - 1 - lead - cols
    for i in range(rows):
        r = rows - 1 - i if reverse_rows else i
        # The row's runs, left to right.
        n_runs = 0
        grey = 0
        count = 0
        total = 0.0
        done = 0  # columns accounted for
        for block in range(marks.shape[1]):
            if marks[r, block] == 0:
                continue
            marks[r, block] = 0
            first = block << BLOCK_SHIFT
            if first >= cols:
                continue
            count += first - done  # the unmarked stretch repeats the last grey
            done = min(first + (1 << BLOCK_SHIFT), cols)
            for c in range(first, done):
                step = acc[r, c]
                if step != 0.0:
                    total += step
                    acc[r, c] = 0.0
                    level = _grey_level(total, antialias)
                    if level != grey:
                        if count > 0:
                            run_values[n_runs], run_lengths[n_runs] = grey, count
                            n_runs += 1
                        grey, count = level, 0
                count += 1
        count += cols - done
        run_values[n_runs], run_lengths[n_runs] = grey, count
        n_runs += 1
        acc[r, cols] = 0.0
        acc[r, cols + 1] = 0.0
        # The scanline, each piece merged into the run in progress when it repeats its byte.
        for j in range(n_runs + 2):
            if j == 0:
                piece_value, piece_length = 0, 1 + lead
            elif j == n_runs + 1:
                piece_value, piece_length = 0, trail
            else:
                k = n_runs - j if reverse_cols else j - 1
                piece_value, piece_length = run_values[k], run_lengths[k]
            if piece_length == 0:
                continue
            if piece_value == value:
                length += piece_length
            else:
                if length > 0:
                    n_items = _push_run(items, n_items, freq, value, length)
                    adler_a, adler_b = _adler_run(adler_a, adler_b, value, length)
                value, length = piece_value, piece_length
    if length > 0:
        n_items = _push_run(items, n_items, freq, value, length)
        adler_a, adler_b = _adler_run(adler_a, adler_b, value, length)
    return _write_block(items, n_items, freq, out), (adler_b << 16) | adler_a


def deflate_bound(rows: int, row_bytes: int) -> int:
    """Bytes that :func:`_deflate_layer` may write for ``rows`` scanlines: a fixed-code block's worst case."""
    return (rows * row_bytes * 9) // 8 + 64


@njit(cache=True)
def _deflate_runs(values, lengths, items, out):
    freq = np.zeros(286, dtype=np.int64)
    n_items = 0
    a, b = 1, 0
    for j in range(values.size):
        if lengths[j] > 0:
            n_items = _push_run(items, n_items, freq, values[j], lengths[j])
            a, b = _adler_run(a, b, values[j], lengths[j])
    return _write_block(items, n_items, freq, out), (b << 16) | a


def deflate_runs(values: np.ndarray, lengths: np.ndarray) -> tuple[bytes, int]:
    """Runs of bytes (``lengths[j]`` copies of ``values[j]``) as a raw deflate block ending on a full flush.

    The encoder of :func:`_deflate_layer` on its own: literals and matches at distance 1
    under a Huffman code made for them (or the fixed code where shorter), RFC 1951.

    Returns
    -------
    stream, adler
        The raw deflate stream (no zlib header; not a final block) and the adler-32 of the
        bytes it inflates to.
    """
    values = np.asarray(values)
    lengths = np.asarray(lengths)
    if values.shape != lengths.shape or values.ndim != 1:
        raise ValueError("runs: expected values and lengths of one same 1-D shape")
    if values.size and (values.min() < 0 or values.max() > 255 or lengths.min() < 0):
        raise ValueError("runs: expected byte values 0-255 and lengths >= 0")
    total = int(lengths.sum())
    items = np.empty(max(total, 1), dtype=np.int16)
    out = np.empty(deflate_bound(1, total), dtype=np.uint8)
    n_bytes, adler = _deflate_runs(values.astype(np.int64), lengths.astype(np.int64), items, out)
    return out[:n_bytes].tobytes(), adler
