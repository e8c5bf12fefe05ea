"""A study's output folder: checked, held by one study at a time, and written whole or not at all.

- A folder is taken if it is new, empty, one a study wrote (its manifest.json), or one a study
  began and did not finish (`INCOMPLETE`, below); a folder of someone's own files is refused.
- One study writes it at a time: a lock file beside it (`.<name>.taa-study-lock`, the cache's
  lock: study.engine.store.lock_file) is held from the start of the study to its end; a second
  study exits naming the folder and the process that holds it. A lock whose process is gone is
  broken.
- Nothing is made until there is a report to write: a study that fails leaves no folder behind.
- A first report (no manifest yet) is written into a hidden sibling folder and renamed into place,
  so an interruption (SIGINT, SIGTERM, a full disk) leaves no half-written folder; a study's next
  report rewrites the folder in place, each file atomically and the manifest last, so an
  interrupted one leaves the previous manifest, which the next study reads.
- A write that fails (a full disk, a read-only folder) is one message naming the folder, the file
  and the reason.
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
import tempfile
from pathlib import Path

INCOMPLETE = ".taa-study-incomplete"     # in a folder whose first report is being moved into place


CANNOT_WRITE = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM})


def write_failure(exc: OSError, folder) -> str:
    """'file: why' for a file that could not be written under `folder`, with the disk's free space
    when it is full."""
    from study.engine.disk import free_bytes
    what = Path(exc.filename).name if getattr(exc, "filename", None) else "a file"
    why = exc.strerror or str(exc)
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        why = f"{why}: {free_bytes(Path(folder)) / 2 ** 20:.1f} MB free on its disk"
    return f"{what}: {why}"


class OutFolderError(ValueError):
    """The output folder cannot be used or written; the message names it and why."""


class OutFolder:
    """`with OutFolder(path) as out: ... out.write(fn)`: `fn(folder)` writes the report into the
    folder it is given (see the module docstring). Raises OutFolderError."""

    def __init__(self, path, log=None):
        self.path = Path(path)
        self.log = log
        self._lock = None
        self._made: list[Path] = []      # parent folders made for the lock, removed if nothing was written
        self.written = False

    @property
    def staging(self) -> Path:
        return self.path.parent / f".{self.path.name}.taa-study-partial"

    @property
    def lock_path(self) -> Path:
        return self.path.parent / f".{self.path.name}.taa-study-lock"

    def check(self) -> None:
        """The folder is usable (module docstring); its nearest existing folder is writable."""
        p = self.path
        if p.exists() and not p.is_dir():
            raise OutFolderError(f"--out {p}: exists and is not a folder")
        if p.is_dir() and not self._ours(p):
            raise OutFolderError(f"--out {p}: the folder holds files but no manifest.json of this tool; "
                                 "give a new or empty folder, or one a study wrote")
        probe_in = p if p.is_dir() else next((a for a in p.absolute().parents if a.exists()), Path("/"))
        if not probe_in.is_dir():
            raise OutFolderError(f"--out {p}: {probe_in} is not a folder")
        try:
            fd, probe = tempfile.mkstemp(dir=probe_in, prefix=".taa-write-test-")
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            raise OutFolderError(f"--out {p}: cannot write there ({exc.strerror or exc})") from None

    @staticmethod
    def _ours(p: Path) -> bool:
        entries = list(p.iterdir())
        return not entries or (p / "manifest.json").is_file() or (p / INCOMPLETE).is_file()

    def __enter__(self) -> "OutFolder":
        from study.engine.store import LockBusy, lock_file
        self.check()
        parent = self.path.absolute().parent
        missing = [a for a in [parent, *parent.parents] if not a.exists()]
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutFolderError(f"--out {self.path}: cannot make {parent} ({exc.strerror or exc})") from None
        self._made = missing
        self._lock = lock_file(self.lock_path, self.log, wait=False)
        try:
            self._lock.__enter__()
        except LockBusy as busy:
            self._lock = None
            self._remove_made()
            raise OutFolderError(f"--out {self.path}: another study is writing this folder (process {busy.pid} "
                                 f"on host {busy.host}, lock {busy.path}); wait for it to finish or give "
                                 "another folder") from None
        with contextlib.suppress(FileNotFoundError):      # a first report interrupted by a signal
            shutil.rmtree(self.staging)
        return self

    def __exit__(self, *exc) -> None:
        with contextlib.suppress(FileNotFoundError):
            shutil.rmtree(self.staging)
        if not self.written:
            self._remove_made()
        if self._lock is not None:
            self._lock.__exit__(None, None, None)
            self._lock = None

    def _remove_made(self) -> None:
        for d in self._made:                              # the deepest first; only if empty
            with contextlib.suppress(OSError):
                d.rmdir()

    def write(self, fn) -> None:
        """`fn(folder)` writes the report: into a hidden sibling renamed into place for a first
        report, else into the folder itself. A failed write raises OutFolderError."""
        first = not (self.path / "manifest.json").is_file()
        where = self.staging if first else self.path
        try:
            if first:
                where.mkdir()
            fn(where)
            if first:
                self._move_into_place()
        except OSError as exc:
            raise OutFolderError(self._failed(exc, first)) from None
        self.written = True

    def _failed(self, exc: OSError, first: bool) -> str:
        left = ("nothing was written" if first else
                "its previous report's manifest still stands; the next study rewrites what it lacks")
        return f"--out {self.path}: cannot write the report ({write_failure(exc, self.path.absolute().parent)}); {left}"

    def _move_into_place(self) -> None:
        """The staged report becomes the folder: a rename where it does not exist yet; into an
        existing (empty, or an earlier incomplete) folder entry by entry under a marker that says
        it is this tool's and incomplete, the manifest last."""
        if not self.path.exists():
            try:
                os.rename(self.staging, self.path)
                return
            except OSError as exc:
                if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY, errno.EXDEV, errno.EBUSY):
                    raise
        entries = list(self.path.iterdir())
        if entries and not (self.path / INCOMPLETE).is_file():     # not ours: someone's files came meanwhile
            raise OutFolderError(f"--out {self.path}: files appeared in the folder while the study ran; "
                                 "nothing was written")
        (self.path / INCOMPLETE).write_text("a study's report being moved into place (taa-study)\n")
        for old in self.path.iterdir():                    # an earlier incomplete move's leftovers
            if old.name != INCOMPLETE:
                shutil.rmtree(old) if old.is_dir() and not old.is_symlink() else old.unlink()
        entries = sorted(self.staging.iterdir(), key=lambda e: e.name == "manifest.json")
        for e in entries:
            os.replace(e, self.path / e.name)
        (self.path / INCOMPLETE).unlink()
        self.staging.rmdir()
