"""The typer application, its consoles and its one error boundary.

Every command is parse → one application function → print. A :class:`PrintappError`
raised anywhere below a command becomes its one-sentence message on stderr and its
exit code (2 for bad input, 3 for a failed verification), here and nowhere else. User
text (file names, design names, messages that quote them) is printed as plain text,
never as Rich markup.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.text import Text
from typer.core import TyperGroup

from printapp.errors import PrintappError

if TYPE_CHECKING:
    from printapp.interrupts import Interrupted

err = Console(stderr=True, highlight=False, soft_wrap=True, markup=False)
out = Console(highlight=False, soft_wrap=True, markup=False)
if not out.is_terminal:
    out.width = 160  # piped output: do not squeeze tables to 80 columns


class _Commands(TyperGroup):
    """The command group with printapp's error boundary."""

    def invoke(self, ctx):  # noqa: ANN001, ANN201 (click's signature)
        try:
            return super().invoke(ctx)
        except PrintappError as exc:
            err.print(Text("error: ", style="bold red") + Text(str(exc)))
            raise typer.Exit(exc.exit_code) from None


app = typer.Typer(
    name="printapp",
    cls=_Commands,
    help="Appearance printing: textures to watertight resin prints, verified by path tracing.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Help texts are plain: Rich markup would swallow every "[default ...]" and "[env ...]".
    rich_markup_mode=None,
)

QuietOption = Annotated[
    bool, typer.Option("--quiet", "-q", help="No progress bars, only the summary and errors.")
]
ForceOption = Annotated[
    bool, typer.Option("--force", help="Write the model even when the design fails verification.")
]


@contextmanager
def working(label: str, quiet: bool) -> Iterator[None]:
    """A status line on stderr (spinner and elapsed time) while a command works, unless ``quiet``."""
    from printapp.progress import StageTimer

    with StageTimer(quiet=quiet) as timer, timer.stage("command", label):
        yield


def percent(value: float | None) -> str:
    """A fraction as a percentage, or why there is none."""
    return "n/a (too few rays)" if value is None else f"{value:.1%}"


def warn(message: str) -> None:
    """One warning line on stderr."""
    err.print(Text("warning: ", style="bold yellow") + Text(message))


def wrote(paths: list[Path], indent: str = "  ") -> None:
    """One ``wrote PATH`` line per output."""
    for path in paths:
        out.print(f"{indent}wrote {path}")


def _version_callback(value: bool) -> None:
    if value:
        from importlib.metadata import version

        out.print(f"printapp {version('printapp')}")
        raise typer.Exit(0)


def _max_memory(text: str | None) -> str | None:
    if text is not None:
        from printapp.memory import parse_size, set_budget

        try:
            set_budget(parse_size(text))
        except ValueError as exc:
            raise typer.BadParameter(str(exc)) from None
    return text


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version_callback, is_eager=True, help="Show the version.")
    ] = False,
    max_memory: Annotated[
        str | None,
        typer.Option(
            "--max-memory",
            callback=_max_memory,
            help="Memory budget, e.g. 8G [half the available memory; env PRINTAPP_MAX_MEMORY].",
        ),
    ] = None,
) -> None:
    """Appearance printing: textures to watertight resin prints, verified by path tracing."""


def main() -> None:
    """Console-script entry point: the app, with Ctrl-C and SIGTERM ending it cleanly (exit 130, 143).

    A command that ends (with any exit code) leaves the process through :func:`_exit_now`.
    """
    from printapp.interrupts import Interrupted, install_handlers, received

    install_handlers()
    try:
        app()
    except Interrupted as exc:
        _exit_interrupted(exc)
    except SystemExit as done:
        signum = received()
        if signum is None:
            _exit_now(done.code)
        # The signal was swallowed somewhere below, but every output was held back.
        _exit_interrupted(Interrupted(signum))
    except BaseException:
        signum = received()
        if signum is None:
            raise
        # The signal struck inside an extension's initialisation (Dr.Jit's, while Mitsuba was
        # imported), which turned it into an ImportError and then a NameError; the output
        # folder was cleaned up on the way out, as for any error.
        _exit_interrupted(Interrupted(signum))


def _exit_interrupted(stopped: Interrupted) -> None:
    """One line for the signal, then its exit code (130 or 143)."""
    err.print(f"{stopped.name}; no partial outputs were left")
    _exit_now(stopped.exit_code)


def _exit_now(code: object) -> None:
    """End the process as ``sys.exit(code)`` would, without tearing the interpreter down.

    Everything a normal exit runs that can matter still runs, in the same order: the wait for
    other threads (and the thread pools' own exit), the ``atexit`` handlers (temporary
    folders, logging) and flushing the standard streams. What is skipped is freeing every
    module and extension one by one, which numba's LLVM, trimesh and Mitsuba made about 0.5 s
    of every command (measured: 0.50 s from the last line to the process's end, 0.03 s
    without it), a quarter of ``printapp slice`` on a small model.
    """
    import atexit
    import contextlib
    import os
    import threading

    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:  # sys.exit("message"): print it, exit 1, as Python does
        print(code, file=sys.stderr)
        status = 1
    shutdown = getattr(threading, "_shutdown", None)  # joins the non-daemon threads, as exit does
    if shutdown is not None:
        shutdown()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe: nothing more can reach it
            stream.flush()
    os._exit(status)
