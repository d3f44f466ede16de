"""Stage timing and rich progress display for long-running commands."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

from printapp.interrupts import check as check_interrupt


class StageTimer:
    """Times named stages and shows each as a progress line on stderr unless ``quiet``."""

    def __init__(self, quiet: bool = False, console: Console | None = None) -> None:
        self.seconds: dict[str, float] = {}
        self.background: set[str] = set()
        """The stages timed on a background thread, alongside the others (:mod:`printapp.background`)."""
        self.console = console or Console(stderr=True)
        self._progress = Progress(
            SpinnerColumn(),
            TextColumn("{task.description:<34}"),
            BarColumn(bar_width=24),
            TimeElapsedColumn(),
            console=self.console,
            disable=quiet,
            transient=False,
        )

    def __enter__(self) -> StageTimer:
        self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._progress.stop()

    @contextmanager
    def stage(self, name: str, label: str, background: bool = False) -> Iterator[None]:
        """Time the block as stage ``name``; show ``label`` while it runs. A ``background`` stage
        runs beside the others (its seconds overlap theirs)."""
        check_interrupt()
        if background:
            self.background.add(name)  # a Ctrl-C that a dependency swallowed stops the run here
        task = self._progress.add_task(label, total=None)
        start = time.perf_counter()
        try:
            yield
            check_interrupt()
        finally:
            self.seconds[name] = round(time.perf_counter() - start, 4)
            self._progress.update(task, total=1, completed=1)
