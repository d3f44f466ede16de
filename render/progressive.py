"""Samples of a Mitsuba scene, averaged per pixel in a fixed order: deterministic, stratified, in passes.

``mi.render`` adds the samples of a pixel into its film with atomics, whose order (and so
whose rounding) changes from run to run when a pixel takes several samples in one pass.
Here the camera rays are made and traced through the scene's integrator directly
(``sensor.sample_ray_differential``, ``integrator.sample``), one lane per sample, pixel-major,
and each pixel's samples are summed in a fixed order (Dr.Jit's evaluated block reduction,
one block of lanes per pixel, no atomics): the same scene, sample count and seed give the
same image, byte for byte, whatever the thread count (tests/test_render.py checks it at one
and at two threads).

The samples come from :mod:`render.sampler` (padded (0, 2)-sequences, every dimension shuffled
and scrambled on its own): within one pass the ``spp`` samples of a pixel (1, 4, 16 or 64) are
stratified in each dimension the path asks for (the pixel's area, the light's area, the BSDF's
lobe). Larger powers of four are traced as passes of 64, as they were for Mitsuba's
``multijitter`` (whose grid for 256 is not 256). Two passes with different seeds are independent
randomisations, which is what the noise estimate of :mod:`render.convergence` needs (its tests
check the halves' independence against a reference; note that the sampler needs
``set_samples_per_wavefront``, or every lane gets sample 0 and nothing is stratified).

Before it: Mitsuba's ``ldsampler``, whose shared scramble made the V-groove tile's image move by
1.25 % (60 standard errors) with the coat's mirror probability, and then ``multijitter``
(unbiased, but 27 % noisier than ``ldsampler`` on a flat tile rendered with its compact BRDF:
37 samples for 2 % where :mod:`render.sampler` takes 23; on the CAD previews, which printapp's own
path loop renders, the two are alike). Mitsuba's
``stratified`` seeds consecutive dimensions' shuffles with consecutive integers and is biased too
(-0.45 % there). docs/benchmarks.md, "commands", sixteenth and seventeenth runs.

On Mitsuba's ``scalar_rgb`` variant (no vectorised Python loop) the film is rendered the old
way: one independent sample per pixel of a ``k`` times finer film per pass, averaged in numpy.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from render import sampler as padded

LANES_PER_CALL = 4_000_000
"""Most samples traced in one call (memory: about 100 bytes a lane in the LLVM backend)."""

_FINE_FILM_SAMPLES = 8_000_000

SAMPLER = padded.NAME
"""The sampler for the camera's paths: :mod:`render.sampler` (module doc: why not Mitsuba's)."""

MAX_PASS_SPP = 64
"""Samples of a pixel in one stratified pass: a power of four whose multi-jittered grid is exact."""


def _mix(seed: int, a: int, b: int = 0) -> int:
    """A 32-bit seed from a seed and two counters (splitmix-style), so that passes and row blocks differ."""
    x = (int(seed) * 0x9E3779B1 + int(a) * 0x85EBCA77 + int(b) * 0xC2B2AE3D + 0x27D4EB2F) & 0xFFFFFFFFFFFFFFFF
    x ^= x >> 31
    x = (x * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    x ^= x >> 29
    return int(x & 0xFFFFFFFF)


def _square_power_of_two(spp: int) -> bool:
    """1, 4, 16, 64...: the sample counts a pass takes (powers of four; above 64, several passes)."""
    return spp >= 1 and spp & (spp - 1) == 0 and (spp.bit_length() - 1) % 2 == 0


def passes_of(spp: int) -> list[int]:
    """``spp`` as passes of powers of four, largest first (its base-4 digits): 100 = 64 + 3 x 16 + 4."""
    out = []
    power = 1
    while power * 4 <= spp:
        power *= 4
    rest = int(spp)
    while rest > 0:
        out += [power] * (rest // power)
        rest %= power
        power //= 4
    return out


class SampleRenderer:
    """A loaded scene whose passes can be rendered one at a time (variant already chosen).

    Parameters
    ----------
    scene_dict : dict
        A Mitsuba scene description with one perspective sensor whose film is
        ``width_px`` x ``height_px``.
    """

    def __init__(self, scene_dict: dict[str, Any], width_px: int, height_px: int) -> None:
        import mitsuba as mi

        self.width = int(width_px)
        self.height = int(height_px)
        self.scalar = mi.variant().startswith("scalar")
        self._dict = dict(scene_dict)
        self.scene = mi.load_dict(scene_dict) if not self.scalar else None
        # The lamps' transforms held in memory, as move_shapes holds them: Mitsuba's rectangle keeps
        # those it is loaded with as literals, which the traced kernels bake in, so every new object
        # size or framing compiled the preview's kernels anew (five, 2.3 s on the demo here). This
        # costs one BVH rebuild at load (0.1-0.2 s on the demo's relief).
        lamps = {
            name: entry["to_world"]
            for name, entry in self._dict.items()
            if isinstance(entry, dict) and entry.get("type") == "rectangle" and "emitter" in entry
        }
        if lamps and self.scene is not None:
            self.move_shapes(lamps)

    def has(self, name: str) -> bool:
        """Whether the scene has an object named ``name`` (a key of its dictionary)."""
        return name in self._dict

    def move_shapes(self, to_world: dict[str, Any]) -> None:
        """Give the named shapes (the lamps' rectangles) new ``to_world`` transforms, in place.

        Cheaper than loading the scene again: the meshes stay where they are (Mitsuba rebuilds
        its BVH, but not the meshes, plugins or kernels). A name the scene lacks is an error.
        """
        import mitsuba as mi

        for name, transform in to_world.items():
            if name not in self._dict:
                raise KeyError(f"the scene has no shape named {name!r}")
            self._dict[name] = dict(self._dict[name], to_world=transform)
        if self.scene is not None:
            import drjit as dr

            params = mi.traverse(self.scene)
            for name, transform in to_world.items():
                # Opaque: a rectangle's transform given as a scalar is baked into the traced
                # kernel as literals, so every new lamp position compiled a new kernel (0.55 s a
                # sweep frame on 2 cores); held in memory, one kernel serves every position.
                moved = mi.Transform4f(transform)
                dr.make_opaque(moved)
                params[f"{name}.to_world"] = moved
            params.update()

    @property
    def scene_dict(self) -> dict[str, Any]:
        """The scene's description, with the lamps where :meth:`move_shapes` put them."""
        return self._dict

    def render(
        self, spp: int, seed: int, pixels: np.ndarray | None = None, integrator: Any = None
    ) -> np.ndarray:
        """The mean of ``spp`` samples per pixel: ``(height, width, 3)`` float64 linear RGB.

        With ``pixels`` (flat indices ``row * width + column``), only those pixels are traced and
        a ``(len(pixels), 3)`` array comes back (the others cost nothing). ``integrator`` (an
        object with Mitsuba's ``sample`` signature) replaces the scene's own on the vectorised
        variants.
        """
        if spp < 1:
            raise ValueError(f"spp: expected at least 1, got {spp}")
        if self.scalar:
            image = self._render_film(spp, seed)
            return image if pixels is None else image.reshape(-1, 3)[np.asarray(pixels)]
        if pixels is None:
            return self._trace(self.scene, spp, seed, 3, integrator=integrator)
        return self._trace(
            self.scene, spp, seed, 3, pixels=np.asarray(pixels, dtype=np.int64), integrator=integrator
        )

    def aovs(self, spp: int, seed: int) -> dict[str, np.ndarray]:
        """Per-pixel means of the surface albedo, shading normal and coverage over ``spp`` samples.

        ``albedo`` and ``normal`` are ``(height, width, 3)`` (zero where the ray sees the
        background); ``coverage`` is the fraction of the pixel's samples that hit a surface.
        """
        import mitsuba as mi

        spec = {"type": "aov", "aovs": "albedo:albedo,normal:sh_normal,depth:depth"}
        scene_dict = dict(self._dict)
        scene_dict["integrator"] = spec
        if self.scalar:
            scene_dict["sensor"] = dict(scene_dict["sensor"])
            scene_dict["sensor"]["film"] = dict(scene_dict["sensor"]["film"], pixel_format="rgb")
            import drjit as dr

            out = np.array(mi.render(mi.load_dict(scene_dict), spp=1), dtype=np.float64)
            dr.sync_thread()
            values = out[..., 3:]
        else:
            # The same scene (no second BVH), traced with the AOV integrator.
            values = self._trace(self.scene, spp, seed, 7, aov=True, integrator=mi.load_dict(spec))
        hit = values[..., 6:7]
        return {"albedo": values[..., 0:3], "normal": values[..., 3:6], "coverage": hit[..., 0]}

    # --- internals ---------------------------------------------------------------------------

    def _trace(
        self,
        scene: Any,
        spp: int,
        seed: int,
        channels: int,
        aov: bool = False,
        pixels: np.ndarray | None = None,
        integrator: Any = None,
    ) -> np.ndarray:
        if not _square_power_of_two(spp):
            raise ValueError(f"spp: the stratified sampler needs a power of four, got {spp}")
        w, h = self.width, self.height
        sensor = scene.sensors()[0]
        integrator = integrator if integrator is not None else scene.integrator()
        count = w * h if pixels is None else int(pixels.size)
        passes = max(1, spp // MAX_PASS_SPP)
        spp = min(spp, MAX_PASS_SPP)
        per_call = max(1, min(count, LANES_PER_CALL // spp))
        out = np.zeros((count, channels), dtype=np.float64)
        for first in range(0, count, per_call):
            for k in range(passes):
                out[first : first + per_call] += self._trace_block(
                    scene,
                    sensor,
                    integrator,
                    spp,
                    _mix(seed, first, k),
                    first,
                    min(per_call, count - first),
                    channels,
                    aov,
                    pixels,
                )
        out /= passes
        return out.reshape(h, w, channels) if pixels is None else out

    def _trace_block(
        self,
        scene: Any,
        sensor: Any,
        integrator: Any,
        spp: int,
        seed: int,
        first: int,
        n_pix: int,
        channels: int,
        aov: bool,
        pixels: np.ndarray | None,
    ) -> np.ndarray:
        """One stratified pass of ``spp`` samples over ``n_pix`` pixels from ``first``: their means."""
        import drjit as dr
        import mitsuba as mi

        w, h = self.width, self.height
        lanes = n_pix * spp
        if SAMPLER == padded.NAME:
            padded.register()
        sampler = mi.load_dict({"type": SAMPLER, "sample_count": int(spp)})
        # Without this the sampler numbers every lane's sample 0: no stratification.
        sampler.set_samples_per_wavefront(int(spp))
        sampler.seed(seed, lanes)
        local = dr.arange(mi.UInt32, lanes) // spp
        if pixels is None:
            pixel = local + first
        else:
            table = mi.UInt32(np.ascontiguousarray(pixels[first : first + n_pix], dtype=np.uint32))
            pixel = dr.gather(mi.UInt32, table, local)
        x = mi.Float(pixel % w)
        y = mi.Float(pixel // w)
        offset = sampler.next_2d()
        position = mi.Point2f((x + offset.x) / w, (y + offset.y) / h)
        ray, weight = sensor.sample_ray_differential(0.0, 0.0, position, mi.Point2f(0.5, 0.5))
        spectrum, _, aovs = integrator.sample(scene, sampler, ray, None, True)
        if aov:
            # albedo (3), normal (3), and whether the ray hit (depth > 0). Evaluated together:
            # converting them one by one ran (and compiled) the whole trace once per channel.
            # Summed per pixel like the colour below (copying every sample out cost 0.85 s of
            # the demo's seven renders).
            lanes_aov = [*aovs[:6], dr.select(aovs[6] > 0.0, mi.Float(1.0), mi.Float(0.0))]
            dr.eval(*lanes_aov)
            sums = [dr.block_reduce(dr.ReduceOp.Add, a, spp, mode="evaluated") for a in lanes_aov]
            dr.eval(*sums)
            dr.sync_thread()
            return np.stack([np.array(a, dtype=np.float64) for a in sums], -1) / spp
        # Each pixel's samples summed in Dr.Jit, one block of lanes per pixel: the
        # "evaluated" reduction adds a block in a fixed order (no atomics), and copying
        # the sums out is spp times less than copying every sample (at 64 spp over 158k
        # pixels, 2.9 s a pass against 3.2 s). The trace is evaluated first: handed
        # unevaluated to the reduction, it ran 2.7 times slower.
        values = spectrum * weight
        dr.eval(values)
        sums = dr.block_reduce(dr.ReduceOp.Add, values, spp, mode="evaluated")
        dr.eval(sums)
        dr.sync_thread()
        return np.array(sums, dtype=np.float64).T / spp

    def _render_film(self, spp: int, seed: int) -> np.ndarray:
        """scalar_rgb: k x k independent samples per pixel per pass on a finer film."""
        import drjit as dr
        import mitsuba as mi

        k = _supersampling(spp, self.width * self.height)
        scene_dict = dict(self._dict)
        sensor = dict(scene_dict["sensor"])
        sensor["film"] = dict(sensor["film"], width=self.width * k, height=self.height * k)
        sensor["sampler"] = {"type": "independent", "sample_count": 1, "seed": int(seed)}
        scene_dict["sensor"] = sensor
        scene = mi.load_dict(scene_dict)
        total = np.zeros((self.height, self.width, 3), dtype=np.float64)
        passes = max(1, spp // (k * k))
        for p in range(passes):
            image = mi.render(scene, spp=1, seed=_mix(seed, p))
            dr.sync_thread()
            fine = np.array(image, dtype=np.float64).reshape(self.height, k, self.width, k, -1)[..., :3]
            total += fine.mean(axis=(1, 3))
        return total / passes


def _supersampling(spp: int, pixels: int) -> int:
    """The largest k with k^2 dividing ``spp`` and k^2 * pixels within one pass's budget."""
    best = 1
    k = 1
    while k * k <= spp and k * k * pixels <= max(_FINE_FILM_SAMPLES, pixels):
        if spp % (k * k) == 0:
            best = k
        k += 1
    return best
