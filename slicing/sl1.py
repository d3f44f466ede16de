"""``.sl1`` archives as PrusaSlicer 2.5 writes them: layer PNGs, ``config.ini``, ``prusaslicer.ini``.

The layers come from :mod:`slicing.layers` (placement, pixel conventions). Pixels are
8-bit grey, 0 dark and 255 cured; with anti-aliasing (PrusaSlicer's ``gamma_correction =
1``) edge pixels carry their exact area coverage.

* The archive is a zip with no folders (the ini files deflated, the layer PNGs stored: their
  streams are deflated already, and deflating them again cost a tenth of a second on an
  800-layer part to save 30 % of the archive): ``config.ini``,
  ``prusaslicer.ini``, then ``<job>00000.png``, ``<job>00001.png``, ...

Everything here builds bytes or writes to a stream the caller opens; no file paths.
"""

from __future__ import annotations

import io
import os
import struct
import threading
import zipfile
import zlib
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from importlib import resources
from typing import BinaryIO

import numpy as np

from slicing.layers import Slices
from slicing.printers import PrinterProfile

FADED_LAYERS = 10
FAST_TILT_S = 5.0
SLOW_TILT_S = 8.0
AREA_FILL_PERCENT = 50.0
SLOW_MOVE_DELAY_S = 1.0
"""PrusaSlicer's "exposure_slow_move_delay_before": a slow layer waits a second more."""
TOWER_S_PER_MM = 5.0
"""PrusaSlicer's tower move time per millimetre of layer height."""
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


def _png(width: int, height: int, idat: bytes) -> bytes:
    def chunk(kind: bytes, body: bytes) -> bytes:
        return (
            struct.pack(">I", len(body))
            + kind
            + body
            + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
        )

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def _deflate(data) -> bytes:
    """zlib stream at the fastest level: ISA-L's deflate (several times zlib's speed) when present."""
    try:
        from isal import isal_zlib
    except ImportError:
        return zlib.compress(data, 1)
    return isal_zlib.compress(data, 1)


def encode_png_grey(image: np.ndarray) -> bytes:
    """An 8-bit greyscale PNG (filter type 0 on every row, one IDAT), as PrusaSlicer writes."""
    rows, cols = image.shape
    raw = np.zeros((rows, cols + 1), dtype=np.uint8)
    raw[:, 1:] = image
    return _png(cols, rows, _deflate(raw))


_ZERO_RUNS: dict[int, bytes] = {}


def _zero_run(length: int) -> bytes:
    """Raw deflate of ``length`` zero bytes (a power of two), ending on a full flush."""
    chunk = _ZERO_RUNS.get(length)
    if chunk is None:
        # Level 6 packs zeros 4.5x tighter than level 1 (2 KB per 2 MB); each run is
        # compressed once per process, so its cost does not matter.
        compressor = zlib.compressobj(6, zlib.DEFLATED, -15)
        chunk = compressor.compress(bytes(length)) + compressor.flush(zlib.Z_FULL_FLUSH)
        _ZERO_RUNS[length] = chunk
    return chunk


def _zero_rows(n_rows: int, row_bytes: int) -> bytes:
    """Raw deflate of ``n_rows`` all-dark scanlines, ending on a full flush (so it can be spliced).

    Spliced from cached runs of zeros whose lengths are the powers of two in the byte
    count, so a process compresses at most a few dozen runs however the part's rows
    move from layer to layer.
    """
    length = n_rows * row_bytes
    return b"".join(_zero_run(1 << bit) for bit in range(length.bit_length()) if length >> bit & 1)


def _adler32_of_zeros(adler: int, length: int) -> int:
    # Zero bytes leave the running sum a unchanged and add `length` times a to b.
    a, b = adler & 0xFFFF, adler >> 16
    return (((b + length * a) % 65521) << 16) | a


def encode_display_png(block: np.ndarray, row0: int, col0: int, shape: tuple[int, int]) -> bytes:
    """The PNG of a display that is dark except for ``block`` at (row0, col0).

    The part's rows go through zlib-ng's level 2 (see :func:`_display_png` for the rest).
    ISA-L's level 1, which they went through before (2.5 times as fast), gave other bytes
    for the same rows now and then (the same pixels): 1 or 2 of every ten ``slice`` runs
    of an 800-layer sphere wrote a layer that differed from the other runs' in a few
    bytes, through its streaming and its one-shot deflate alike, with the input's
    contents, alignment and trailing bytes held fixed.
    """
    from zlib_ng import zlib_ng

    height, width = block.shape
    part, adler = b"", 1
    if height > 0:
        # Compressed and summed through the buffer protocol: no copy into bytes.
        data = np.zeros((height, shape[1] + 1), dtype=np.uint8)
        data[:, 1 + col0 : 1 + col0 + width] = block
        compressor = zlib_ng.compressobj(2, zlib_ng.DEFLATED, -15)
        part = compressor.compress(data) + compressor.flush(zlib_ng.Z_FULL_FLUSH)
        adler = zlib_ng.adler32(data)
    return _display_png(shape, row0, height, part, adler)


def _display_png(shape: tuple[int, int], row0: int, height: int, part: bytes, part_adler: int) -> bytes:
    """The PNG of a display that is dark except for ``height`` rows from ``row0``.

    ``part`` is the raw deflate of those rows' scanlines, ending on a full flush, and
    ``part_adler`` their adler-32 started from 1. The zlib stream is spliced from parts
    that each end on a full flush: cached chunks for the dark rows above and below, and
    the part. The adler-32 of the dark rows is in closed form. Only the part's rows are
    ever compressed, which is what makes layers cheap.
    """
    rows, cols = shape
    row_bytes = cols + 1
    pieces = [b"\x78\x01"]
    a, b = part_adler & 0xFFFF, part_adler >> 16
    if row0 > 0:
        pieces.append(_zero_rows(row0, row_bytes))
        # Zeros first leave s1 at 1 and s2 at their count; the part then adds as from (1, 0).
        b = (b + row0 * row_bytes) % 65521
    if height > 0:
        pieces.append(part)
    adler = (b << 16) | a
    tail = rows - row0 - height
    if tail > 0:
        pieces.append(_zero_rows(tail, row_bytes))
        adler = _adler32_of_zeros(adler, tail * row_bytes)
    pieces += [b"\x03\x00", struct.pack(">I", adler)]  # an empty final block, then the checksum
    return _png(cols, rows, b"".join(pieces))


@dataclass
class LayerStats:
    """Per-layer cured area (mm^2), the slow-tilt decision, and the total resin volume (ml)."""

    areas_mm2: list[float]
    volume_ml: float

    def slow(self, display_area_mm2: float) -> list[bool]:
        """Per layer: whether it cures more than the area-fill share of the display (a slow tilt)."""
        return [a > AREA_FILL_PERCENT / 100.0 * display_area_mm2 for a in self.areas_mm2]

    def n_slow(self, display_area_mm2: float) -> int:
        return sum(self.slow(display_area_mm2))


def encoded_layers(slices: Slices, workers: int = 2) -> Iterator[tuple[int, bytes]]:
    """(k, PNG bytes) per layer, in order; rasterised and encoded on ``workers`` threads.

    The numba rasteriser and the deflate both release the GIL. The bytes do not depend
    on the number of workers.
    """
    local = threading.local()
    shape = slices.display_shape()
    # Layers whose pixels are the geometric slice's are deflated as they are rasterised;
    # a subclass that lights its pixels otherwise (exposure from heights) goes through its image.
    straight = type(slices).layer_grey is Slices.layer_grey

    def make(k: int) -> bytes:
        scratch = getattr(local, "scratch", None)
        if scratch is None:
            scratch = local.scratch = {}
        if straight:
            part, adler, row0, height = slices.deflate_display_rows(k, scratch)
            return _display_png(shape, row0, height, part, adler)
        block, r0, c0 = slices.display_block(*slices.layer_grey(k, scratch))
        return encode_display_png(block, r0, c0, shape)

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        pending: list = []
        for k in range(slices.n_layers):
            pending.append((k, pool.submit(make, k)))
            if len(pending) > 4 * workers:
                k0, future = pending.pop(0)
                yield k0, future.result()
        for k0, future in pending:
            yield k0, future.result()


def _timestamp() -> tuple[tuple[int, ...], str]:
    """Zip and config timestamps: SOURCE_DATE_EPOCH when set (reproducible builds), else 1980-01-01."""
    import time

    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    t = time.gmtime(int(epoch)) if epoch and epoch.isdigit() else time.gmtime(315532800)
    stamp = (max(t.tm_year, 1980), t.tm_mon, t.tm_mday, t.tm_hour, t.tm_min, t.tm_sec)
    text = (
        f"{t.tm_year:04d}-{t.tm_mon:02d}-{t.tm_mday:02d} at {t.tm_hour:02d}:{t.tm_min:02d}:{t.tm_sec:02d} UTC"
    )
    return stamp, text


def _prusaslicer_ini(profile: PrinterProfile, layer_height_mm: float) -> str:
    text = resources.files("slicing").joinpath("prusaslicer_sl1_template.ini").read_text(encoding="utf-8")
    values = dict(
        line.split(" = ", 1) for line in text.splitlines() if " = " in line and not line.startswith("#")
    )
    values.update(
        {
            "display_width": f"{profile.display_width_mm:g}",
            "display_height": f"{profile.display_height_mm:g}",
            "display_pixels_x": str(profile.display_pixels_x),
            "display_pixels_y": str(profile.display_pixels_y),
            "display_orientation": profile.orientation,
            "display_mirror_x": str(int(profile.mirror_x)),
            "display_mirror_y": str(int(profile.mirror_y)),
            "gamma_correction": "1" if profile.antialiasing else "0",
            "layer_height": f"{layer_height_mm:g}",
            "initial_layer_height": f"{profile.initial_layer_height_mm:g}",
            "exposure_time": f"{profile.exposure_s:g}",
            "initial_exposure_time": f"{profile.initial_exposure_s:g}",
            "max_print_height": f"{profile.max_print_height_mm:g}",
            "printer_settings_id": profile.label,
        }
    )
    return "".join(f"{k} = {v}\n" for k, v in sorted(values.items()))


def print_time_s(profile: PrinterProfile, layer_heights_mm: list[float], slow: list[bool]) -> float:
    """The print time PrusaSlicer 2.5 writes (``SLAPrint::Steps::merge_slices_and_eval_stats``).

    Per layer: its exposure (the first three layers at the initial time; then the time
    steps down by ``(initial - normal) / (faded + 1)`` until it reaches the normal time),
    the tilt (slow for layers curing more than ``area_fill`` of the display, else fast),
    one more second before a slow layer's exposure, and ``5 s/mm`` of tower move for the
    layer's height. Checked against PrusaSlicer 2.5's config.ini on the SL1 profile
    (exactly, for fast and slow layers; see tests/test_slicing.py).
    """
    exposure, initial = profile.exposure_s, profile.initial_exposure_s
    delta = (initial - exposure) / (FADED_LAYERS + 1)
    fading = initial
    total = 0.0
    for k, (height, is_slow) in enumerate(zip(layer_heights_mm, slow, strict=True)):
        if k < 3:
            time = initial
        elif fading > exposure:
            fading -= delta
            time = fading
        else:
            time = exposure
        time += SLOW_TILT_S + SLOW_MOVE_DELAY_S if is_slow else FAST_TILT_S
        total += time + height * TOWER_S_PER_MM
    return total


def write_sl1(stream: BinaryIO, slices: Slices, job_name: str, workers: int = 2) -> LayerStats:
    """Write the sliced part as a PrusaSlicer 2.5 ``.sl1`` archive to ``stream``.

    Layers are encoded as they are rasterised, so memory stays at a few layers.
    """
    p = slices.profile
    stamp, stamp_text = _timestamp()
    # config.ini comes first in the archive and needs the layers' areas: exact section
    # areas, from the segments, before any layer is rasterised.
    areas = [float(a) for a in slices.section_areas_mm2()]
    thickness = [p.initial_layer_height_mm] + [slices.layer_height_mm] * (len(areas) - 1)
    stats = LayerStats(areas_mm2=areas, volume_ml=float(np.dot(areas, thickness)) / 1000.0)
    slow = stats.slow(p.display_width_mm * p.display_height_mm)
    n_slow = sum(slow)
    from importlib.metadata import version

    config = {
        "action": "print",
        "expTime": f"{p.exposure_s:g}",
        "expTimeFirst": f"{p.initial_exposure_s:g}",
        "expUserProfile": "0",
        "fileCreationTimestamp": stamp_text,
        "hollow": "0",
        "jobDir": job_name,
        "layerHeight": f"{slices.layer_height_mm:g}",
        "materialName": "printapp resin",
        "numFade": str(FADED_LAYERS),
        "numFast": str(slices.n_layers - n_slow),
        "numSlow": str(n_slow),
        "printProfile": f"{slices.layer_height_mm:g} printapp",
        "printTime": f"{print_time_s(p, thickness, slow):.6f}",
        "printerModel": p.name.replace("prusa-", "").upper(),
        "printerProfile": p.label,
        "printerVariant": "default",
        "prusaSlicerVersion": f"printapp-{version('printapp')}",
        "usedMaterial": f"{stats.volume_ml:.6f}",
    }
    with zipfile.ZipFile(stream, "w") as archive:
        for name, text in (
            ("config.ini", "".join(f"{k} = {v}\n" for k, v in sorted(config.items()))),
            ("prusaslicer.ini", _prusaslicer_ini(p, slices.layer_height_mm)),
        ):
            info = zipfile.ZipInfo(name, date_time=stamp)
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, text.encode("utf-8"))
        for k, png in encoded_layers(slices, workers):
            info = zipfile.ZipInfo(f"{job_name}{k:05d}.png", date_time=stamp)
            info.compress_type = zipfile.ZIP_STORED
            archive.writestr(info, png)
    return stats


def read_sl1(stream: BinaryIO) -> tuple[dict[str, str], list[np.ndarray]]:
    """Read an ``.sl1`` archive: its config.ini as a dict and its layers as uint8 images.

    Raises
    ------
    ValueError
        If the archive lacks config.ini or its layers are not the 8-bit grey PNGs it names.
    """
    from PIL import Image

    try:
        archive = zipfile.ZipFile(stream)
    except zipfile.BadZipFile:
        raise ValueError("expected an .sl1 archive (a zip file)") from None
    with archive:
        try:
            config_text = archive.read("config.ini").decode("utf-8")
        except KeyError:
            raise ValueError("expected config.ini in the .sl1 archive") from None
        config = dict(line.split(" = ", 1) for line in config_text.splitlines() if " = " in line)
        job = config.get("jobDir", "")
        count = int(config.get("numFast", "0")) + int(config.get("numSlow", "0"))
        layers = []
        for k in range(count):
            name = f"{job}{k:05d}.png"
            try:
                image = Image.open(io.BytesIO(archive.read(name)))
            except KeyError:
                raise ValueError(f"expected layer {name} in the .sl1 archive") from None
            if image.mode != "L":
                raise ValueError(f"{name}: expected an 8-bit grey PNG, found mode {image.mode}")
            layers.append(np.asarray(image))
    return config, layers
