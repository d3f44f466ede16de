"""Ctrl-C and SIGTERM: a run ends with exit 130 or 143, one line, and no partial output.

The command line installs :func:`install_handlers`; a signal then raises
:class:`Interrupted` wherever the main thread is. Some dependencies wrap their optional
imports in ``except BaseException`` and would swallow it, so the signal is also
remembered: :func:`check` raises it again at every stage boundary and before any output
is moved into place, so a swallowed interrupt cannot let a run finish and write.

A signal that arrives while a module is being imported is held until the import is over
(polled every :data:`RETRY_S`): an extension that runs Python code while it initialises
(Mitsuba's enums, as Dr.Jit's nanobind builds them) cannot pass a Python exception back,
and nanobind ends the process with ``std::terminate`` instead (SIGABRT and a C++ traceback,
seen when Ctrl-C struck in the first seconds of ``printapp design``).
"""

from __future__ import annotations

import signal
from types import FrameType

_received: int | None = None

RETRY_S = 0.05
"""How often a signal held during an import looks again whether the import is over (s)."""


class Interrupted(BaseException):  # noqa: N818 (it is a signal, not an error)
    """The run was stopped by a signal; ``exit_code`` is 128 + the signal's number."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return 128 + self.signum

    @property
    def name(self) -> str:
        return "interrupted" if self.signum == signal.SIGINT else "terminated"


def _importing(frame: FrameType | None) -> bool:
    """Whether the main thread is inside an import (importlib's frames on its stack)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _handler(signum: int, frame: FrameType | None) -> None:
    global _received
    _received = signum
    if _importing(frame) and hasattr(signal, "setitimer"):
        signal.signal(signal.SIGALRM, _retry)
        signal.setitimer(signal.ITIMER_REAL, RETRY_S)
        return
    raise Interrupted(signum)


def _retry(_signum: int, frame: FrameType | None) -> None:
    """The timer of a signal held during an import: raise it now, or look again later."""
    if _received is not None:
        _handler(_received, frame)


def install_handlers() -> None:
    """Turn SIGINT and SIGTERM into :class:`Interrupted` (main thread only)."""
    signal.signal(signal.SIGINT, _handler)
    signal.signal(signal.SIGTERM, _handler)


def received() -> int | None:
    """The signal received so far, if any."""
    return _received


def check() -> None:
    """Raise :class:`Interrupted` again if a signal arrived (and was swallowed on the way)."""
    if _received is not None:
        raise Interrupted(_received)
