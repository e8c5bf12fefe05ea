"""OpenEXR I/O (float32, ZIP), written atomically: a temporary file in the same folder renamed
into place, so a reader never sees a half-written image.

OpenEXR's Python binding prints some warnings (e.g. "Exception raised reading pixel data" for a
truncated file) through Python's sys.stdout, which would corrupt a `--json` document. Each library
call runs with sys.stdout captured, and with file descriptor 2 too: its C core writes each error
of a damaged file to stderr itself, several times for one file. What either printed goes, once per
line, into the exception message if the call fails, else to stderr.
"""
from __future__ import annotations

import contextlib
import io
import os
import secrets
import sys
import tempfile
from pathlib import Path

import numpy as np
import OpenEXR


class ExrError(ValueError):
    """An EXR file could not be read or written; the message names the file and the library's words."""


@contextlib.contextmanager
def _c_stderr(box: list):
    """Collect what C code writes to file descriptor 2 during the block into `box` (one string)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield box
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            box.append(tmp.read().decode("utf-8", "replace"))


def _call(what: str, path, fn):
    """fn() with the library's stdout and C stderr captured (see the module docstring)."""
    said, c_said = io.StringIO(), []
    try:
        with contextlib.redirect_stdout(said), _c_stderr(c_said):
            result = fn()
    except Exception as exc:
        words = _once(said.getvalue() + "".join(c_said), str(path))
        note = f" (OpenEXR: {words})" if words else ""
        raise ExrError(f"{path}: cannot {what} EXR file: {exc}{note}") from exc
    words = _once(said.getvalue() + "".join(c_said), str(path))
    if words:
        print(f"{path}: OpenEXR: {words}", file=sys.stderr)
    return result


def _once(text: str, path: str) -> str:
    """The library's lines, each once, without the file name it repeats."""
    lines = []
    for line in text.splitlines():
        line = line.strip().removeprefix(path).removeprefix(":").strip()
        if line and line not in lines:
            lines.append(line)
    return "; ".join(lines)


def _new_temp(folder: Path, stem: str) -> Path:
    """An empty file created with mode 0666 less the umask, like any file the user writes
    (tempfile.mkstemp would give 0600, and os.replace keeps the mode)."""
    while True:
        tmp = folder / f"{stem}.{secrets.token_hex(6)}.exr.part"
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return tmp
        except FileExistsError:
            continue


def write_exr(path: Path | str, channels: dict[str, np.ndarray], header: dict | None = None) -> None:
    """channels: name -> (H, W) array, or 'RGB' -> (H, W, 3). Values are stored as float32."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    h = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    h.update(header or {})
    data = {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}
    tmp = _new_temp(path.parent, path.stem)
    try:
        _call("write", path, lambda: OpenEXR.File(h, data).write(str(tmp)))
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def read_exr(path: Path | str) -> tuple[dict, dict[str, np.ndarray]]:
    """(header, channel name -> (H, W) float32 array)."""
    def read():
        f = OpenEXR.File(str(path), separate_channels=True)
        return f.header(), {k: v.pixels for k, v in f.channels().items()}
    return _call("read", path, read)
