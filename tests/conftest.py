"""Scheduling for `pytest -n auto` (pytest-xdist with ``--dist loadgroup``, as the Makefile runs it).

Tests that share an expensive module fixture stay on one worker (an ``xdist_group`` each), so
the fixture runs once; and the heavy tests (marked ``slow``) are handed out first, so that no
worker is left with a long test while the other has finished.
"""

import pytest

SHARED_FIXTURES = ("demo_runs", "vein_fits", "marble_fits", "cylinder_reliefs", "brushed", "passed")
"""Module fixtures of more than a second or two (see ``--durations``)."""


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook, which reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        for name in SHARED_FIXTURES:
            if name in getattr(item, "fixturenames", ()):
                item.add_marker(pytest.mark.xdist_group(name))
                break
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
