"""Integer triples written as XML elements in decimal, by a numba kernel: a 3MF's triangles.

A 3MF model lists each triangle as ``<triangle v1="i" v2="j" v3="k"/>``. Python's %-formatting
writes the 4.1 million numbers of a 1.4 M-triangle part in about 0.9 s (one format call over a
tuple of them); this writes the same bytes (tests/test_exporters.py holds them equal) in a
small fraction of that, two passes over the indices: their lengths, then their digits.
The vertices' ``%.9g`` floats stay with Python's formatting, whose correctly rounded shortest
forms a kernel would have to reproduce digit for digit.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _digits(value: int) -> int:
    count = 1
    while value >= 10:
        value //= 10
        count += 1
    return count


@njit(cache=True, nogil=True)  # (on the background thread: the main one goes on meanwhile)
def _elements(triples, head, seps, tail):
    """``head a seps[0] b seps[1] c tail`` for each row ``(a, b, c)`` of ``triples``, as uint8."""
    fixed = head.size + seps.shape[1] * 2 + tail.size
    total = 0
    for r in range(triples.shape[0]):
        total += fixed + _digits(triples[r, 0]) + _digits(triples[r, 1]) + _digits(triples[r, 2])
    out = np.empty(total, dtype=np.uint8)
    at = 0
    for r in range(triples.shape[0]):
        for q in range(head.size):
            out[at + q] = head[q]
        at += head.size
        for k in range(3):
            value = triples[r, k]
            n = _digits(value)
            for q in range(n - 1, -1, -1):
                out[at + q] = 48 + value % 10
                value //= 10
            at += n
            part = seps[k] if k < 2 else tail
            for q in range(part.size):
                out[at + q] = part[q]
            at += part.size
    return out


def triangle_elements(faces: np.ndarray) -> bytes:
    """``<triangle v1="i" v2="j" v3="k"/>`` for every face, concatenated: ASCII bytes.

    The 3MF Core Specification's triangle element (section 4.1.4.2), each index in plain
    decimal as ``'%d' % i`` writes it. ``faces`` is ``(F, 3)`` non-negative integers.
    """
    tris = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(tris) and int(tris.min()) < 0:
        raise ValueError(f"faces: expected non-negative vertex indices, found {int(tris.min())}")

    def ascii(text: str) -> np.ndarray:
        return np.frombuffer(text.encode("ascii"), dtype=np.uint8)

    # Both separators are six bytes long, so they fit one array.
    seps = np.stack([ascii('" v2="'), ascii('" v3="')])
    return _elements(tris, ascii('<triangle v1="'), seps, ascii('"/>')).tobytes()
