"""The LIC bench's own arithmetic: rlic's reach in pixels, and the round-robin timer."""

import numpy as np
import pytest

from printapp.bench import interleaved_seconds
from printapp.bench.lic import pixel_crossings_per_px


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 45.0, 120.0])
def test_pixel_crossings_of_a_constant_field(angle_deg):
    a = np.radians(angle_deg)
    u = np.full((8, 8), np.cos(a))
    v = np.full((8, 8), np.sin(a))
    assert pixel_crossings_per_px(u, v) == pytest.approx(abs(np.cos(a)) + abs(np.sin(a)))


def test_pixel_crossings_of_random_directions_average_four_over_pi():
    a = np.random.default_rng(0).uniform(0, 2 * np.pi, (400, 400))
    assert pixel_crossings_per_px(np.cos(a), np.sin(a)) == pytest.approx(4 / np.pi, rel=0.005)


def test_rlic_taps_span_length_over_crossings():
    """rlic takes one tap per pixel edge crossed: 2L + 1 taps reach L px along x but
    L / sqrt(2) on a diagonal, and round(L * crossings) taps reach L px there too."""
    rlic = pytest.importorskip("rlic")
    n, length = 101, 20
    for angle in (0.0, 45.0):
        a = np.radians(angle)
        u = np.full((n, n), np.cos(a))
        v = np.full((n, n), np.sin(a))
        texture = np.full((n, n), 1e-9)
        texture[50, 50] = 1.0
        taps = round(length * pixel_crossings_per_px(u, v))
        out = rlic.convolve(texture, u, v, kernel=np.ones(2 * taps + 1))
        jj, ii = np.nonzero(out > 0.5 / (2 * taps + 1))
        reach = np.hypot(ii - 50, jj - 50).max()
        assert reach == pytest.approx(length, abs=1.5)


def test_interleaved_seconds_warms_up_then_times_each_in_turn():
    calls: list[str] = []

    def record(name: str):
        return lambda: calls.append(name) or name

    fns = {"a": record("a"), "b": record("b")}
    seconds, last, cores = interleaved_seconds(fns, 2, {"a": record("warm a")})
    assert calls == ["warm a", "a", "b", "a", "b"]  # b had no warm-up: a dict replaces them all
    assert last == {"a": "a", "b": "b"}
    assert set(seconds) == set(cores) == {"a", "b"} and all(s >= 0 for s in seconds.values())
    calls.clear()
    interleaved_seconds({"a": record("a")}, 1)
    assert calls == ["a", "a"]  # without warmups, each is called once untimed first
