"""The preview's stratified sampler (render.progressive) against independent references: an image
must not move with a sampling parameter, must agree with Mitsuba's own film loop and its independent
sampler, and passes above 64 samples must lower the variance as their count says. Statistical,
with fixed seeds; the "where it fails" case is Mitsuba's ``ldsampler``, which this module used
until it was found to fail the first check."""

import numpy as np
import pytest

from render.convergence import LUMINANCE
from tests.scenes import coated_grooves_renderer

WIDTH, HEIGHT = 96, 72
SPP = 64
SEEDS = 16


def _renderer(mirror_probability: float):
    """The V-groove tile, its coat drawing the mirror with this probability."""
    from render.mitsuba_adapter import choose_variant

    if choose_variant().variant.startswith("scalar"):
        pytest.skip("the stratified sampler runs on Mitsuba's vectorised variants")
    return coated_grooves_renderer(mirror_probability, WIDTH, HEIGHT)


@pytest.fixture(scope="module")
def mask():
    """The tile's pixels, fixed once (the means below must be over the same pixels)."""
    return _renderer(0.7).aovs(16, 0)["coverage"] >= 0.5


def _means(renderer, mask, spp=SPP, seeds=range(SEEDS)):
    """The object's mean luminance in independent renders."""
    return np.array([(renderer.render(spp, 1000 + s) @ LUMINANCE)[mask].mean() for s in seeds])


def _z(a: np.ndarray, b: np.ndarray) -> float:
    """How many standard errors apart two sets of independent estimates' means are."""
    se = np.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
    return abs(a.mean() - b.mean()) / se


def test_the_image_does_not_move_with_the_coats_mirror_probability(mask):
    drawn_often, drawn_less = _means(_renderer(0.7), mask), _means(_renderer(0.4), mask)
    assert _z(drawn_often, drawn_less) < 4.0
    assert drawn_often.mean() == pytest.approx(drawn_less.mean(), rel=0.002)


@pytest.mark.slow
def test_the_image_agrees_with_mitsubas_film_loop_and_independent_sampler(mask):
    import mitsuba as mi

    renderer = _renderer(0.4)
    ours = _means(renderer, mask)
    scene_dict = dict(renderer.scene_dict)
    sensor = dict(scene_dict["sensor"])
    sensor["film"] = dict(sensor["film"], rfilter={"type": "box"})  # each sample in its own pixel
    sensor["sampler"] = {"type": "independent", "sample_count": SPP}
    scene_dict["sensor"] = sensor
    scene = mi.load_dict(scene_dict)

    def film_loop(seed: int) -> np.ndarray:
        return np.asarray(mi.render(scene, seed=seed), dtype=np.float64)[..., :3] @ LUMINANCE

    theirs = np.array([film_loop(7 + 131 * s)[mask].mean() for s in range(2 * SEEDS)])
    assert _z(ours, theirs) < 4.0
    # and stratified: a pixel's variance well under the independent sampler's (2.3x on this tile)
    ours_pixels = np.stack([renderer.render(SPP, 1000 + s) @ LUMINANCE for s in range(8)])[:, mask]
    theirs_pixels = np.stack([film_loop(7 + 131 * s) for s in range(8)])[:, mask]
    assert ours_pixels.var(0, ddof=1).mean() < 0.7 * theirs_pixels.var(0, ddof=1).mean()


def test_mitsubas_ldsampler_fails_the_mirror_probability_check(mask, monkeypatch):
    """Where it fails: ``ldsampler`` scrambles every dimension of a pixel with the same bits, so the
    lobe choices at two bounces are correlated; its mean moves by about 1.2 % (60 standard errors)."""
    import render.progressive

    monkeypatch.setattr(render.progressive, "SAMPLER", "ldsampler")
    drawn_often, drawn_less = _means(_renderer(0.7), mask), _means(_renderer(0.4), mask)
    assert _z(drawn_often, drawn_less) > 10.0


def test_a_pass_above_64_samples_is_deterministic_and_as_good_as_its_count():
    renderer = _renderer(0.7)
    one = renderer.render(256, 5)
    assert np.array_equal(one, renderer.render(256, 5))
    many = np.stack([renderer.render(256, 10 + s) @ LUMINANCE for s in range(6)])
    few = np.stack([renderer.render(64, 20 + s) @ LUMINANCE for s in range(6)])
    ratio = many.var(0, ddof=1).mean() / few.var(0, ddof=1).mean()
    assert 0.18 < ratio < 0.32  # four independent passes of 64: a quarter of the variance


# --- render.sampler itself --------------------------------------------------------------------


def _vectorised():
    from render.mitsuba_adapter import choose_variant

    if choose_variant().variant.startswith("scalar"):
        pytest.skip("the sampler runs on Mitsuba's vectorised variants")
    import mitsuba as mi

    from render import sampler

    return mi, sampler


def test_the_one_pass_permutation_is_kenslers_for_powers_of_two():
    """Each step is a bijection on the low bits, so Kensler's rejection loop is never taken: the
    one-expression form is a permutation, and the same one Mitsuba's ``permute_kensler`` gives."""
    mi, sampler = _vectorised()
    import drjit as dr

    for n in (1, 4, 16, 64, 256):
        for seed in (0, 12345, 0xDEADBEEF):
            index = dr.arange(mi.UInt32, n)
            ours = np.array(sampler.permute_pow2(index, n - 1, mi.UInt32(seed)))
            assert sorted(ours.tolist()) == list(range(n))
            assert np.array_equal(ours, np.array(mi.permute_kensler(index, n, mi.UInt32(seed))))


def test_a_symbolic_loop_draws_what_is_drawn_outside_it():
    """Dr.Jit's symbolic loops rebuild the sampler from its default constructor (sample count 4)
    and set its ``DRJIT_STRUCT`` fields: the draws inside a loop whose lanes stop at different
    iterations must be the draws made one after another outside it. (With the sample count kept
    as a plain attribute, the loop drew as if each pixel had four samples, and printapp's own path
    loop came out 5 times noisier than independent sampling.)"""
    mi, sampler = _vectorised()
    import drjit as dr

    lanes, spp = 64, 16

    def fresh():
        s = mi.load_dict({"type": sampler.register(), "sample_count": spp})
        s.set_samples_per_wavefront(spp)
        s.seed(7, lanes)
        return s

    s = fresh()
    drawn = [np.array(s.next_2d().x) if k % 2 == 0 else np.array(s.next_1d()) for k in range(8)]

    @dr.syntax
    def loop(s):
        import drjit as dr  # (dr.syntax rebuilds the function: the test's locals are not seen)
        import mitsuba as mi

        k, total, on = mi.UInt32(0), mi.Float(0.0), mi.Bool(True)
        while on:
            pair = s.next_2d(on)
            single = s.next_1d(on)
            total += dr.select(on, pair.x + single, 0.0)
            k += 1
            on &= (k < 4) & (single > 0.3)
        return total, k

    total, steps = (np.array(v) for v in loop(fresh()))
    assert len(set(steps.tolist())) > 1  # lanes did stop at different iterations
    want = np.array(
        [sum(drawn[2 * i][j] + drawn[2 * i + 1][j] for i in range(steps[j])) for j in range(lanes)]
    )
    assert np.allclose(total, want, atol=1e-5)


def test_a_pixels_samples_are_stratified_in_every_dimension_and_pixels_differ():
    """Within a pixel the ``spp`` values of a 1-D dimension fall one in each of ``spp`` strata, and
    of a 2-D dimension one in each elementary interval of a (0, 2)-net (checked on the 4 x 4 and
    the 16 x 1 grids); two pixels, and two dimensions, are not the same points."""
    mi, sampler = _vectorised()
    spp = 16
    s = mi.load_dict({"type": sampler.register(), "sample_count": spp})
    s.set_samples_per_wavefront(spp)
    s.seed(3, 2 * spp)
    one = np.array(s.next_1d()).reshape(2, spp)
    pair = np.array(s.next_2d()).T.reshape(2, spp, 2)
    other = np.array(s.next_1d()).reshape(2, spp)
    for pixel in range(2):
        assert sorted(np.floor(one[pixel] * spp).astype(int)) == list(range(spp))
        x, y = pair[pixel, :, 0], pair[pixel, :, 1]
        assert len(set(zip(np.floor(x * 4), np.floor(y * 4), strict=True))) == spp
        assert sorted(np.floor(x * spp).astype(int)) == list(range(spp))
        assert sorted(np.floor(y * spp).astype(int)) == list(range(spp))
    assert not np.allclose(np.sort(one[0]), np.sort(one[1]))
    assert not np.allclose(np.sort(one[0]), np.sort(other[0]))
