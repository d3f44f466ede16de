"""Layer images on a printer's display, and ``.sl1`` archives as PrusaSlicer 2.5 writes them.

Conventions (PrusaSlicer 2.5, checked against its output):

* The part is dropped to z = 0 and its bounding box centred on the display, which
  covers bed X in [0, display_width] and Y in [0, display_height].
* A top view T has columns X / pitch and rows (H - Y) / pitch; a portrait display shows
  ``rot90(T, 1)``; ``mirror_x`` then flips left-right and ``mirror_y`` up-down.
* Slice heights: see :func:`slicing.raster.slice_heights`.
* Pixels are 8-bit grey, 0 dark and 255 cured; with anti-aliasing (PrusaSlicer's
  ``gamma_correction = 1``) edge pixels carry their exact area coverage.
* The archive is a zip of deflated entries with no folders: ``config.ini``,
  ``prusaslicer.ini``, then ``<job>00000.png``, ``<job>00001.png``, ...

Everything here builds bytes or writes to a stream the caller opens; no file paths.
"""

from __future__ import annotations

import io
import math
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

from noise.heightfield import HeightField
from slicing.printers import PrinterProfile
from slicing.raster import (
    _layer_box,
    _max_winding,
    _rasterise_layer_grey,
    heightfield_segments,
    rasterise_sections,
    section_areas,
    section_segments,
    slice_heights,
)

FADED_LAYERS = 10
FAST_TILT_S = 5.0
SLOW_TILT_S = 8.0
AREA_FILL_PERCENT = 50.0
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


@dataclass
class Slices:
    """A sliced part: its layers' coverage on a window of the display, and where the window sits.

    ``coverage(k)`` is the (rows, cols) fraction of each pixel cured in layer k, in bed
    coordinates (row 0 at the smallest Y, column 0 at the smallest X) for the window whose
    lower-left pixel is ``(col0, row0)`` of the top view's bed-aligned pixel grid.
    """

    profile: PrinterProfile
    heights_mm: np.ndarray
    layer_height_mm: float
    shift_mm: np.ndarray
    """Translation from the input mesh's coordinates to bed coordinates (mm)."""
    col0: int
    row0: int
    cols: int
    rows: int
    antialias: bool
    _layer: np.ndarray
    _segments: np.ndarray

    @property
    def n_layers(self) -> int:
        return int(self.heights_mm.size)

    def coverages(self) -> Iterator[tuple[int, np.ndarray]]:
        """(k, coverage) for every layer, in order; the array is reused between layers."""
        p = self.profile
        origin = (self.col0 * p.pitch_x_mm, self.row0 * p.pitch_y_mm)
        yield from rasterise_sections(
            self._layer,
            self._segments,
            self.n_layers,
            origin,
            (p.pitch_x_mm, p.pitch_y_mm),
            (self.rows, self.cols),
        )

    def grey(self, coverage: np.ndarray) -> np.ndarray:
        """Coverage to 8-bit grey: exact coverage with anti-aliasing, else cured where over half covered."""
        if self.antialias:
            return np.round(coverage * 255.0).astype(np.uint8)
        return np.where(coverage >= 0.5, 255, 0).astype(np.uint8)

    def layer_grey(self, k: int, scratch: dict | None = None) -> tuple[np.ndarray, int, int]:
        """Layer k as 8-bit grey on the part of the window it touches, and that part's (row, column).

        Releases the GIL, so layers can be made on threads.
        """
        p = self.profile
        ox, oy, r0, r1, c0, c1 = self._layer_window(k)
        bounds = self._bounds
        scratch = {} if scratch is None else scratch
        acc = scratch.get("acc")
        if acc is None or acc.shape != (self.rows, self.cols + 2):
            acc = scratch["acc"] = np.zeros((self.rows, self.cols + 2))
        out = np.empty((r1 - r0, c1 - c0), dtype=np.uint8)
        _rasterise_layer_grey(
            self._segments,
            bounds[k],
            bounds[k + 1],
            ox + c0 * p.pitch_x_mm,
            oy + r0 * p.pitch_y_mm,
            1.0 / p.pitch_x_mm,
            1.0 / p.pitch_y_mm,
            self.antialias,
            acc[: r1 - r0, : c1 - c0 + 2],
            out,
        )
        return out, r0, c0

    def _layer_window(self, k: int) -> tuple[float, float, int, int, int, int]:
        """The window's origin (mm) and the rows [r0, r1) and columns [c0, c1) layer k touches."""
        p = self.profile
        ox, oy = self.col0 * p.pitch_x_mm, self.row0 * p.pitch_y_mm
        bounds = self._bounds
        r0, r1, c0, c1 = _layer_box(
            self._segments,
            bounds[k],
            bounds[k + 1],
            ox,
            oy,
            1.0 / p.pitch_x_mm,
            1.0 / p.pitch_y_mm,
            self.rows,
            self.cols,
        )
        return ox, oy, r0, r1, c0, c1

    @property
    def _bounds(self) -> np.ndarray:
        cached = getattr(self, "_bounds_cache", None)
        if cached is None:
            cached = np.searchsorted(self._layer, np.arange(self.n_layers + 1), side="left")
            self._bounds_cache = cached
        return cached

    def max_winding(self) -> float:
        """Largest winding number (pixel-averaged) over all layers: 1 for a solid that does not
        overlap itself, 2 or more where its surface passes through itself (as the printer sees it).
        """
        p = self.profile
        acc = np.zeros((self.rows, self.cols + 2))
        bounds = self._bounds
        worst = 0.0
        for k in range(self.n_layers):
            ox, oy, r0, r1, c0, c1 = self._layer_window(k)
            worst = max(
                worst,
                _max_winding(
                    self._segments,
                    bounds[k],
                    bounds[k + 1],
                    ox + c0 * p.pitch_x_mm,
                    oy + r0 * p.pitch_y_mm,
                    1.0 / p.pitch_x_mm,
                    1.0 / p.pitch_y_mm,
                    acc[: r1 - r0, : c1 - c0 + 2],
                ),
            )
        return worst

    def section_areas_mm2(self) -> np.ndarray:
        """Exact area of each layer's cross-section (mm^2)."""
        return section_areas(self._layer, self._segments, self.n_layers)

    def display_block(self, grey: np.ndarray, row: int = 0, col: int = 0) -> tuple[np.ndarray, int, int]:
        """Grey pixels (at ``row``, ``col`` of the window) as they appear on the display.

        Returns a view (not a copy) and its top-left (row, column) on the display.
        """
        p = self.profile
        # In the top view T (H_px x W_px, row 0 at the largest Y) the block occupies
        # rows [a0, a0 + h) and columns [b0, b0 + w).
        block = grey[::-1]
        a0 = p.display_pixels_y - (self.row0 + row) - grey.shape[0]
        b0 = self.col0 + col
        height, width = p.display_pixels_y, p.display_pixels_x
        if p.orientation == "portrait":
            # rot90(T, 1): T[a, b] -> P[W - 1 - b, a]
            block = np.rot90(block, 1)
            a0, b0 = width - (b0 + grey.shape[1]), a0
            height, width = width, height
        if p.mirror_x:
            block = block[:, ::-1]
            b0 = width - (b0 + block.shape[1])
        if p.mirror_y:
            block = block[::-1]
            a0 = height - (a0 + block.shape[0])
        return block, a0, b0

    def display_shape(self) -> tuple[int, int]:
        p = self.profile
        if p.orientation == "portrait":
            return p.display_pixels_x, p.display_pixels_y
        return p.display_pixels_y, p.display_pixels_x

    def display_image(self, grey_window: np.ndarray) -> np.ndarray:
        """The whole display's image for one layer, oriented and mirrored like PrusaSlicer's."""
        block, r0, c0 = self.display_block(grey_window)
        image = np.zeros(self.display_shape(), dtype=np.uint8)
        image[r0 : r0 + block.shape[0], c0 : c0 + block.shape[1]] = block
        return image


def slice_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    profile: PrinterProfile,
    *,
    layer_height_mm: float | None = None,
    antialias: bool | None = None,
) -> Slices:
    """Slice a closed, outward-oriented mesh (mm) for ``profile``, PrusaSlicer's way.

    Raises
    ------
    ValueError
        If the mesh is empty, or larger than the display or the printable height (the
        message says by how much), or the layer height is outside the profile's range.
    """
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    if verts.size == 0 or tris.size == 0:
        raise ValueError("model: expected a mesh with triangles, found none")
    lh = _check_layer_height(profile, layer_height_mm)
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    shift = _placement(lo, hi, profile)
    heights = slice_heights(float(hi[2] - lo[2]), lh, profile.initial_layer_height_mm)
    layer, segments = section_segments(verts + shift, tris, heights)
    return _slices(profile, heights, lh, shift, lo, hi, antialias, layer, segments)


def slice_heightfield(
    field: HeightField,
    base_thickness_mm: float,
    profile: PrinterProfile,
    *,
    layer_height_mm: float | None = None,
    antialias: bool | None = None,
) -> Slices:
    """Slice a relief tile straight from its height field, without building a mesh.

    The solid is the closed slab that :func:`printapp.mesh.slab_from_heightfield` would
    build (top triangulated along each cell's v00-v11 diagonal, vertical walls, floor at
    z = 0); its sections are computed triangle by triangle from the grid, so the layers
    are the same as slicing that mesh, at a fraction of the memory for large maps.
    The field's origin places it in x and y.
    """
    h = np.ascontiguousarray(field.heights_mm, dtype=np.float64)
    pitch_x_mm, pitch_y_mm = field.pitch_x_mm, field.pitch_y_mm
    origin_mm = (field.origin_x_mm, field.origin_y_mm)
    if h.ndim != 2 or min(h.shape) < 2 or not np.all(np.isfinite(h)):
        raise ValueError("heights: expected a finite 2-D array of at least 2 x 2 samples")
    if not (pitch_x_mm > 0 and pitch_y_mm > 0 and base_thickness_mm > 0):
        raise ValueError("pitch, base thickness: expected positive values")
    if float(h.min()) + base_thickness_mm <= 0:
        raise ValueError("heights: the tile's top must stay above z = 0")
    lh = _check_layer_height(profile, layer_height_mm)
    ny, nx = h.shape
    lo = np.array([origin_mm[0], origin_mm[1], 0.0])
    hi = np.array(
        [
            origin_mm[0] + (nx - 1) * pitch_x_mm,
            origin_mm[1] + (ny - 1) * pitch_y_mm,
            base_thickness_mm + h.max(),
        ]
    )
    shift = _placement(lo, hi, profile)
    heights = slice_heights(float(hi[2]), lh, profile.initial_layer_height_mm)
    layer, segments = heightfield_segments(
        h, pitch_x_mm, pitch_y_mm, base_thickness_mm, origin_mm[0], origin_mm[1], shift, heights
    )
    return _slices(profile, heights, lh, shift, lo, hi, antialias, layer, segments)


def _check_layer_height(profile: PrinterProfile, layer_height_mm: float | None) -> float:
    lh = profile.layer_height_mm if layer_height_mm is None else float(layer_height_mm)
    if not profile.min_layer_height_mm - 1e-12 <= lh <= profile.max_layer_height_mm + 1e-12:
        raise ValueError(
            f"layer height: {lh:g} mm is outside what {profile.label} can print "
            f"([{profile.min_layer_height_mm:g}, {profile.max_layer_height_mm:g}] mm)"
        )
    return lh


def _placement(lo: np.ndarray, hi: np.ndarray, profile: PrinterProfile) -> np.ndarray:
    """The shift that drops the part to z = 0 and centres it on the display; refuses parts too large."""
    size = hi - lo
    w, d = profile.display_width_mm, profile.display_height_mm
    if size[0] > w or size[1] > d or size[2] > profile.max_print_height_mm:
        over = [
            f"{axis} by {s - limit:.2f} mm"
            for axis, s, limit in (
                ("x", size[0], w),
                ("y", size[1], d),
                ("z", size[2], profile.max_print_height_mm),
            )
            if s > limit
        ]
        raise ValueError(
            f"model: {size[0]:.2f} x {size[1]:.2f} x {size[2]:.2f} mm does not fit the {profile.label} "
            f"({w:g} x {d:g} x {profile.max_print_height_mm:g} mm): too large in {', '.join(over)}"
        )
    return -np.array([(lo[0] + hi[0]) / 2 - w / 2, (lo[1] + hi[1]) / 2 - d / 2, lo[2]])


def _slices(profile, heights, lh, shift, lo, hi, antialias, layer, segments) -> Slices:
    px, py = profile.pitch_x_mm, profile.pitch_y_mm
    placed_lo, placed_hi = lo + shift, hi + shift
    col0 = max(int(math.floor(placed_lo[0] / px)) - 1, 0)
    col1 = min(int(math.ceil(placed_hi[0] / px)) + 1, profile.display_pixels_x)
    row0 = max(int(math.floor(placed_lo[1] / py)) - 1, 0)
    row1 = min(int(math.ceil(placed_hi[1] / py)) + 1, profile.display_pixels_y)
    return Slices(
        profile=profile,
        heights_mm=heights,
        layer_height_mm=lh,
        shift_mm=shift,
        col0=col0,
        row0=row0,
        cols=col1 - col0,
        rows=row1 - row0,
        antialias=profile.antialiasing if antialias is None else antialias,
        _layer=layer,
        _segments=segments,
    )


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


_ZERO_ROWS: dict[tuple[int, int], bytes] = {}


def _zero_rows(n_rows: int, row_bytes: int) -> bytes:
    """Raw deflate of ``n_rows`` all-dark scanlines, ending on a full flush (so it can be spliced)."""
    key = (n_rows, row_bytes)
    chunk = _ZERO_ROWS.get(key)
    if chunk is None:
        compressor = zlib.compressobj(1, zlib.DEFLATED, -15)
        chunk = compressor.compress(bytes(n_rows * row_bytes)) + compressor.flush(zlib.Z_FULL_FLUSH)
        _ZERO_ROWS[key] = chunk
    return chunk


def _adler32_of_zeros(adler: int, length: int) -> int:
    # Zero bytes leave the running sum a unchanged and add `length` times a to b.
    a, b = adler & 0xFFFF, adler >> 16
    return (((b + length * a) % 65521) << 16) | a


def encode_display_png(block: np.ndarray, row0: int, col0: int, shape: tuple[int, int]) -> bytes:
    """The PNG of a display that is dark except for ``block`` at (row0, col0).

    The zlib stream is spliced from parts that are each compressed on their own and end
    on a full flush: cached chunks for the dark rows above and below, and the rows that
    hold the part. The adler-32 of the dark rows is computed in closed form. Only the
    part's rows are ever compressed, which is what makes layers cheap.
    """
    from isal import isal_zlib

    rows, cols = shape
    row_bytes = cols + 1
    height, width = block.shape
    pieces = [b"\x78\x01"]
    adler = 1
    if row0 > 0:
        pieces.append(_zero_rows(row0, row_bytes))
        adler = _adler32_of_zeros(adler, row0 * row_bytes)
    if height > 0:
        raw = np.zeros((height, row_bytes), dtype=np.uint8)
        raw[:, 1 + col0 : 1 + col0 + width] = block
        data = raw.tobytes()
        compressor = isal_zlib.compressobj(1, isal_zlib.DEFLATED, -15)
        pieces += [compressor.compress(data), compressor.flush(isal_zlib.Z_FULL_FLUSH)]
        adler = zlib.adler32(data, adler)
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

    def n_slow(self, display_area_mm2: float) -> int:
        return sum(1 for a in self.areas_mm2 if a > AREA_FILL_PERCENT / 100.0 * display_area_mm2)


def encoded_layers(slices: Slices, workers: int = 2) -> Iterator[tuple[int, bytes]]:
    """(k, PNG bytes) per layer, in order; rasterised and encoded on ``workers`` threads.

    The numba rasteriser and the deflate both release the GIL. The bytes do not depend
    on the number of workers.
    """
    local = threading.local()
    shape = slices.display_shape()

    def make(k: int) -> bytes:
        scratch = getattr(local, "scratch", None)
        if scratch is None:
            scratch = local.scratch = {}
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


def print_time_s(profile: PrinterProfile, n_layers: int, n_slow: int) -> float:
    """Exposure (the first layers fading from the initial to the normal time) plus tilts."""
    total = 0.0
    for k in range(n_layers):
        if k == 0:
            total += profile.initial_exposure_s
        elif k <= FADED_LAYERS:
            f = k / (FADED_LAYERS + 1)
            total += profile.initial_exposure_s * (1 - f) + profile.exposure_s * f
        else:
            total += profile.exposure_s
    return total + (n_layers - n_slow) * FAST_TILT_S + n_slow * SLOW_TILT_S


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
    n_slow = stats.n_slow(p.display_width_mm * p.display_height_mm)
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
        "printTime": f"{print_time_s(p, slices.n_layers, n_slow):.6f}",
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
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, png, compresslevel=1)
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
