"""OpenEXR I/O (float32, lossless: ZIP or Zstandard), written atomically: a temporary file in the
same folder renamed into place, so a reader never sees a half-written image.

Every file is stored losslessly (a figure computed from it must not move). Which codec is smaller
depends on the content: ZIP for smooth images (run frames: 0.27 of the raw float32 bytes on the
quick study's 320x180 files; a smooth scene's reference), Zstandard for noisy ones (sphere_ghosting's
references, whose standard errors and floor are path-traced noise: 28 % smaller than ZIP; the
SSIM/FLIP maps: 15 %). `compression="smallest"` writes both and keeps the smaller file. References
are written in Zstandard: on the thesis's 1600x900 references it was smaller or the same on 8 of 12
scenes and at most 16 % larger (arched_window), where writing both cost 0.6-1.6 s of a 10-20 s
reference (docs/performance.md, "Disk"). PIZ, HTJ2K and RLE were larger on every file measured.

OpenEXR's Python binding prints some warnings (e.g. "Exception raised reading pixel data" for a
truncated file) through Python's sys.stdout, which would corrupt a `--json` document, and its C
core writes each error of a damaged file to file descriptor 2 itself, several times for one file.
Each library call runs with both captured; what the library said goes, once per line, into the
exception message if the call fails, else to stderr. sys.stdout and fd 2 belong to the whole
process while the report reads and writes images on a thread pool: one call at a time captures
them (a process-wide lock; the binding holds the GIL through a read anyway), and only the calling
thread's prints are taken from sys.stdout, so another thread's output is neither swallowed nor
left redirected.
"""
from __future__ import annotations

import contextlib
import io
import os
import secrets
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np
import OpenEXR


class ExrError(ValueError):
    """An EXR file could not be read or written; the message names the file and the library's words."""


_LOCK = threading.RLock()       # one library call at a time captures the process's stdout and fd 2


class _ThreadStdout(io.TextIOBase):
    """sys.stdout during one library call: the calling thread's writes are kept, every other
    thread's go to the stream it stands in for. One per stream, never freed: print() holds
    sys.stdout by a borrowed reference (CPython 3.11), so a stand-in freed while another thread
    prints would be used after it is freed."""

    stream = thread = kept = None

    def __init__(self, stream):
        self.stream = stream

    def write(self, s):
        if self.thread is not None and self.thread == threading.get_ident():
            return self.kept.write(s)
        return self.stream.write(s)

    def flush(self):
        self.stream.flush()

    def __getattr__(self, name):          # encoding, fileno, isatty... of the stream
        return getattr(self.stream, name)


_STAND_INS: dict[int, _ThreadStdout] = {}     # id(stream) -> its stand-in (which keeps the stream alive)


def _call(what: str, path, fn):
    """fn() with the library's stdout and C stderr captured (see the module docstring)."""
    with _LOCK:
        stream = sys.stdout
        out = _STAND_INS.get(id(stream))
        if out is None:
            out = _STAND_INS[id(stream)] = _ThreadStdout(stream)
        out.kept, out.thread = io.StringIO(), threading.get_ident()
        sys.stdout = out
        c_said = ""
        try:
            with contextlib.suppress(AttributeError, ValueError, OSError):
                sys.stderr.flush()
            saved = os.dup(2)
            try:
                with tempfile.TemporaryFile() as tmp:
                    os.dup2(tmp.fileno(), 2)
                    try:
                        result = fn()
                    finally:
                        os.dup2(saved, 2)
                        tmp.seek(0)
                        c_said = tmp.read().decode("utf-8", "replace")
            finally:
                os.close(saved)
        except Exception as exc:
            words = _once(out.kept.getvalue() + _theirs(c_said, str(path)), str(path))
            note = f" (OpenEXR: {words})" if words else ""
            raise ExrError(f"{path}: cannot {what} EXR file: {exc}{note}") from exc
        finally:
            if sys.stdout is out:
                sys.stdout = stream
            out.thread = None           # if someone swapped it meanwhile: every write goes through
            said = out.kept.getvalue()
    words = _once(said + _theirs(c_said, str(path)), str(path))
    if words:
        print(f"{path}: OpenEXR: {words}", file=sys.stderr)
    return result


def _theirs(text: str, path: str) -> str:
    """The library's lines of what fd 2 received during a call (it names the file, or the
    temporary file written for it); another thread's lines go on to stderr."""
    stem = str(Path(path).with_suffix(""))
    mine, other = [], []
    for line in text.splitlines(keepends=True):
        (mine if line.startswith(stem) else other).append(line)
    if other:
        sys.stderr.write("".join(other))
    return "".join(mine)


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


# the lossless codecs a file may be written with (OpenEXR >= 3.4 reads Zstandard); "smallest":
# whichever of them makes the smaller file
LOSSLESS = {"zip": OpenEXR.ZIP_COMPRESSION, "zstd": OpenEXR.ZSTD_COMPRESSION}
CODECS = (*LOSSLESS, "smallest")


def write_exr(path: Path | str, channels: dict[str, np.ndarray], header: dict | None = None,
              compression: str = "zip") -> None:
    """Write an EXR file atomically.

    Parameters
    ----------
    path : Path or str
        The file written.
    channels : dict
        name -> (H, W) array, or 'RGB' -> (H, W, 3). Values are stored as float32, bit for bit.
    header : dict, optional
        Extra header attributes.
    compression : {'zip', 'zstd', 'smallest'}
        The lossless codec (LOSSLESS), or 'smallest': each of them tried, the smaller file kept.
    """
    path = Path(path)
    if compression not in CODECS:
        raise ExrError(f"{path}: compression must be one of {list(CODECS)} (lossless), not {compression!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}
    tries = []
    try:
        for codec in LOSSLESS if compression == "smallest" else (compression,):
            h = {"compression": LOSSLESS[codec], "type": OpenEXR.scanlineimage}
            h.update(header or {})
            tmp = _new_temp(path.parent, path.stem)
            tries.append(tmp)
            _call("write", path, lambda h=h, tmp=tmp: OpenEXR.File(h, data).write(str(tmp)))
        os.replace(min(tries, key=os.path.getsize), path)
    finally:
        for tmp in tries:
            if os.path.exists(tmp):
                os.unlink(tmp)


def read_exr(path: Path | str) -> tuple[dict, dict[str, np.ndarray]]:
    """(header, channel name -> (H, W) float32 array)."""
    def read():
        f = OpenEXR.File(str(path), separate_channels=True)
        return f.header(), {k: v.pixels for k, v in f.channels().items()}
    return _call("read", path, read)
