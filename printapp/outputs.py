"""Writing outputs so that nothing half-written, stale or misleading is ever left behind.

- Single files (:func:`atomic_write_files`) are written in full under temporary names
  beside their destinations and renamed into place only when all are written.
- Output folders (:class:`OutputFolder`) are staged in a hidden sibling folder and
  swapped in whole when the run is complete: the folder then holds exactly this run's
  outputs, never a previous run's model beside this run's failed verdict. The folder
  itself is created only then, so a refused or interrupted run creates nothing.
- Files get the mode the user's umask gives (not the 0600 of temporary files).
- A staging folder left by a killed run is removed by the next run into the same place.
- Before anything is moved into place, a pending Ctrl-C or SIGTERM is raised
  (:func:`printapp.interrupts.check`).
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

from printapp.errors import DesignError
from printapp.interrupts import check as check_interrupt

FileContent = bytes | bytearray | memoryview | Callable[[BinaryIO], None]
"""What a file holds: its bytes, or a function that writes them to an open binary file (a large
file streamed as it is made, never held in memory whole)."""


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _current_umask()
FILE_MODE = 0o666 & ~_UMASK
"""Mode of every file printapp writes: what ``open()`` would give under the user's umask."""
FOLDER_MODE = 0o777 & ~_UMASK
_PARTIAL = re.compile(r"^\.(?P<name>.+)\.printapp-(?:partial|old)-(?P<pid>\d+)-[A-Za-z0-9_]+$")


def _folder_of(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path``, then rename it into place.

    Raises
    ------
    DesignError
        If the folder does not exist or cannot be written.
    """
    return atomic_write_files([(Path(path), data)])[0]


def atomic_write_files(outputs: list[tuple[Path, FileContent]]) -> list[Path]:
    """Write several files so that none appears unless all were written.

    Every file is first written in full to a temporary name beside its destination;
    only then are they renamed into place, one ``os.replace`` each (atomic on one file
    system). A failure or an interrupt while writing leaves no output and no temporary file.

    Raises
    ------
    DesignError
        If a folder does not exist or cannot be written, or a destination is a folder.
    """
    paths = [Path(path) for path, _ in outputs]
    for path in paths:
        folder = _folder_of(path)
        if not folder.is_dir():
            raise DesignError(f"{path}: the folder {folder} does not exist")
        if path.is_dir():
            raise DesignError(f"{path}: is a folder, expected a file name")
    staged: list[str] = []
    current = paths[0] if paths else Path(".")
    try:
        for current, (_, data) in zip(paths, outputs, strict=True):
            fd, tmp = tempfile.mkstemp(prefix=f".{current.name}.", suffix=".partial", dir=_folder_of(current))
            staged.append(tmp)
            with os.fdopen(fd, "wb") as handle:
                os.fchmod(handle.fileno(), FILE_MODE)
                if callable(data):
                    data(handle)
                else:
                    handle.write(data)
        check_interrupt()
        for tmp, current in zip(staged, paths, strict=True):
            os.replace(tmp, current)
        staged = []
    except OSError as exc:
        raise DesignError(f"{current}: cannot write the file ({exc.strerror or exc})") from None
    finally:
        for tmp in staged:
            if os.path.exists(tmp):
                os.unlink(tmp)
    return paths


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's live process
    return True


def remove_stale_staging(destination: Path) -> list[Path]:
    """Remove the staging folders that killed runs left beside ``destination``; return them.

    A staging folder's name carries its process id, so a run never removes the staging
    of another run that is still going.
    """
    removed = []
    parent = _folder_of(destination)
    if not parent.is_dir():
        return removed
    for entry in parent.iterdir():
        match = _PARTIAL.match(entry.name)
        if match and match["name"] == destination.name and not _alive(int(match["pid"])):
            shutil.rmtree(entry, ignore_errors=True)
            removed.append(entry)
    # Staging folders of earlier printapp versions lived inside the destination.
    if destination.is_dir():
        for entry in destination.glob(".printapp-partial-*"):
            shutil.rmtree(entry, ignore_errors=True)
            removed.append(entry)
    return removed


class OutputFolder:
    """Stage a run's outputs in a hidden sibling folder; swap them in whole on :meth:`commit`.

    ``owned(name)`` says which files in an existing destination a previous run of the
    same command may have left (default: every file). On commit, an existing
    destination that holds only such files is replaced whole (renamed aside, the staging
    renamed into place, the old one removed); one that also holds other files keeps
    them, gets the new files one ``os.replace`` each, and loses the owned files this
    run did not write. Nothing is created until commit: leaving the block without
    committing (an error, an interrupt) leaves no folder and no file.

    Raises
    ------
    DesignError
        On entering, if the destination is a file or its parent cannot be written; on
        commit, if the folder cannot be moved into place.
    """

    def __init__(self, destination: str | Path, owned: Callable[[str], bool] | None = None) -> None:
        self.given = Path(destination)
        """The destination as the caller named it (the paths :meth:`commit` returns start with it)."""
        self.destination = Path(os.path.abspath(destination))
        self.owned = owned or (lambda name: True)
        self._staging: Path | None = None
        self._created_parents: list[Path] = []
        self._files: list[str] = []

    def __enter__(self) -> OutputFolder:
        dest = self.destination
        try:
            if dest.exists() and not dest.is_dir():
                raise DesignError(f"{dest}: output folder is a file, expected a folder")
            parent = dest.parent
            missing = []
            while not parent.exists():
                missing.append(parent)
                parent = parent.parent
            if not parent.is_dir():
                raise DesignError(f"{dest}: output folder is not writable ({parent} is a file)")
            for folder in reversed(missing):
                folder.mkdir()
                self._created_parents.append(folder)
            remove_stale_staging(dest)
            self._staging = Path(
                tempfile.mkdtemp(prefix=f".{dest.name}.printapp-partial-{os.getpid()}-", dir=dest.parent)
            )
        except OSError as exc:
            self._remove_created_parents()
            raise DesignError(f"{dest}: output folder is not writable ({exc.strerror or exc})") from None
        return self

    def path(self, name: str) -> Path:
        """Where to write ``name`` while staging."""
        assert self._staging is not None, "use OutputFolder as a context manager"
        if name not in self._files:
            self._files.append(name)
        return self._staging / name

    def write_bytes(self, name: str, data: FileContent) -> None:
        """Stage ``name`` with ``data``; a full disk or a lost folder is one sentence, not a traceback."""
        try:
            with open(self.path(name), "wb") as handle:
                if callable(data):
                    data(handle)
                else:
                    handle.write(data)
        except OSError as exc:
            raise DesignError(f"{self.given / name}: cannot write the file ({exc.strerror or exc})") from None

    def write_text(self, name: str, text: str) -> None:
        self.write_bytes(name, text.encode("utf-8"))

    def discard(self, name: str) -> None:
        """Unstage ``name`` (a file written ahead of a verdict that then did not allow it)."""
        path = self.path(name)
        if path.exists():
            path.unlink()
        self._files.remove(name)

    def commit(self) -> list[Path]:
        """Move the staged files into place (see the class); return their final paths."""
        assert self._staging is not None
        check_interrupt()
        staging, dest = self._staging, self.destination
        staged = [name for name in self._files if (staging / name).exists()]
        try:
            for name in staged:
                os.chmod(staging / name, FILE_MODE)
            os.chmod(staging, FOLDER_MODE)
            if not dest.exists():
                os.replace(staging, dest)
            elif dest != Path.cwd() and all(
                entry.is_file() and self.owned(entry.name) for entry in dest.iterdir()
            ):
                prefix = f".{dest.name}.printapp-old-{os.getpid()}-"
                aside = Path(tempfile.mkdtemp(prefix=prefix, dir=staging.parent))
                os.replace(dest, aside / dest.name)
                os.replace(staging, dest)
                shutil.rmtree(aside, ignore_errors=True)
            else:
                for name in staged:
                    os.replace(staging / name, dest / name)
                for entry in dest.iterdir():
                    if entry.is_file() and self.owned(entry.name) and entry.name not in staged:
                        entry.unlink()
        except OSError as exc:
            raise DesignError(f"{dest}: cannot move the outputs into place ({exc.strerror or exc})") from None
        self._created_parents = []
        return [self.given / name for name in staged]

    def _remove_created_parents(self) -> None:
        for folder in reversed(self._created_parents):
            try:
                folder.rmdir()
            except OSError:
                break
        self._created_parents = []

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._staging is not None and self._staging.exists():
            shutil.rmtree(self._staging, ignore_errors=True)
        self._remove_created_parents()
