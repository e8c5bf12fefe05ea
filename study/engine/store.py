"""Make-style, tamper-evident artefact store.

Every artefact lives in a folder named by its content key and is complete only once its
`done.json` (written last, atomically) names that key. The done record lists the SHA-256 of every
file the artefact holds, and carries a hash of its own content; a read checks both, so an edited
value, a file overwritten with garbage or another artefact's file copied in is reported (which
file, expected and found hash) and the artefact is re-made. JSON records (metrics, agreement,
timings) carry the same self-hash.

Writes go to a temporary name and are renamed, with the permissions the user's umask gives.
`lock(key)` serialises work on one key across processes and machines sharing the cache (an
exclusive-create lock file, kept fresh by a heartbeat; a lock whose heartbeat stopped is stale).
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import socket
import sys
import threading
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from provenance.files import _umask, sha256_file, write_bytes_atomic, write_text_atomic
from references.exr import read_exr, write_exr


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-serialisable: {type(o).__name__}")


def _canonical(data: dict) -> bytes:
    body = {k: v for k, v in data.items() if k != "sha256"}
    return json.dumps(body, sort_keys=True, default=_json_default, allow_nan=True).encode()


def seal(data: dict) -> dict:
    """`data` with a hash of its own content, so an edit that keeps the key is detected."""
    return {**data, "sha256": hashlib.sha256(_canonical(data)).hexdigest()}


class TamperError(ValueError):
    pass


def unseal(data: dict, where: Path) -> dict:
    found = hashlib.sha256(_canonical(data)).hexdigest()
    if data.get("sha256") != found:
        raise TamperError(f"{where}: content hash {found[:16]} does not match the recorded "
                          f"{str(data.get('sha256'))[:16]}")
    return data


def codec(name: str) -> str:
    """The lossless codec a folder's file is written with (references.exr.LOSSLESS): Zstandard
    for SSIM/FLIP/video maps (15 % smaller than ZIP on the quick study's), ZIP for images."""
    return "zstd" if name.startswith("maps_") else "zip"


class FolderWriter:
    """A folder being made: it has no done record until `seal`, so a crash leaves it incomplete."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        (self.folder / "done.json").unlink(missing_ok=True)
        self.hashes: dict[str, str] = {}

    def add(self, name: str, data) -> None:
        write_exr(self.folder / name, data if isinstance(data, dict) else {"RGB": data},
                  compression=codec(name))
        self.hashes[name] = sha256_file(self.folder / name)

    def add_png(self, name: str, img8: np.ndarray) -> None:
        """An (H, W, 3) uint8 image as PNG (lossless): a judged frame as the report shows it."""
        from PIL import Image
        buf = io.BytesIO()
        Image.fromarray(np.ascontiguousarray(img8, np.uint8)).save(buf, format="PNG")
        write_bytes_atomic(self.folder / name, buf.getvalue())
        self.hashes[name] = sha256_file(self.folder / name)

    def seal(self, key: str, meta: dict) -> dict:
        return _write_done(self.folder, seal({**meta, "key": key, "files": dict(self.hashes)}))


def _write_done(folder: Path, record: dict) -> dict:
    write_text_atomic(folder / "done.json", json.dumps(record, indent=1, default=_json_default))
    return record


def _dead_owner(owner: str) -> bool:
    """The lock's owner ('host pid thread') is a process of this host that no longer exists."""
    parts = owner.split()
    if len(parts) != 3 or parts[0] != socket.gethostname() or not parts[1].isdigit():
        return False
    try:
        os.kill(int(parts[1]), 0)
    except ProcessLookupError:
        return True
    except OSError:          # exists, another user's
        return False
    # a killed process its parent has not reaped yet (a zombie) still answers signal 0
    with contextlib.suppress(OSError, IndexError):
        return Path(f"/proc/{parts[1]}/stat").read_text().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    return False


_HASHES: dict[str, dict] = {}     # cache root -> {file: [inode, size, mtime_ns, ctime_ns, sha256]}
_CHANGED: set[str] = set()
_SETTLE_NS = 2_000_000_000        # a file changed this recently may change again within one time tick
# done.json path -> (its state, its unsealed record): a study plans twice and its report reads the
# records again; re-parsing and re-hashing ~2900 of them was ~0.3 s of a no-op study. Any write
# changes the state (the change time), so a remembered record is the file's own.
_RECORDS: dict[str, tuple] = {}


def _state(st: os.stat_result) -> list:
    """What any write to a file changes (the change time at least; no tool sets it back)."""
    return [st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]


def _settled(st: os.stat_result) -> bool:
    """Not changed within the last time tick: two writes within one could leave the same state."""
    return time.time_ns() - st.st_ctime_ns > _SETTLE_NS


# (lock file, owner) -> how many times its owner (host, process, thread) entered it: re-entry from
# the thread that holds a lock passes (a heartbeat keeps the file fresh, so waiting on it would hang)
_HELD: dict[tuple[str, str], int] = {}
_HELD_GUARD = threading.Lock()


MISSING, OTHER_KEY, PRUNED, TAMPERED, COMPLETE = "missing", "other key", "pruned", "tampered", "complete"


class Checked(NamedTuple):
    """What Store.check found in a folder: its status, the done record when COMPLETE, and what
    did not match when TAMPERED."""
    status: str
    record: dict | None = None
    problem: str | None = None


class Store:
    """Artefacts under `root`: folders of files with a sealed done record, and sealed JSON records."""

    def __init__(self, root: Path, log=None):
        self.root = Path(root)
        self.log = log or (lambda msg: print(msg, file=sys.stderr))

    # -- folders of files ----------------------------------------------------------------------
    def folder(self, kind: str, scene: str, key: str) -> Path:
        return self.root / "runs" / kind / scene / key

    def save_folder(self, folder: Path, key: str, files: dict[str, np.ndarray | dict], meta: dict) -> dict:
        """Write EXR files (name -> image or channel dict) and then the done record listing their hashes."""
        w = self.writer(folder)
        for name, data in files.items():
            w.add(name, data)
        return w.seal(key, meta)

    def writer(self, folder: Path) -> "FolderWriter":
        """Files one at a time, then the done record (for artefacts too large to hold at once)."""
        return FolderWriter(folder)

    def check(self, folder: Path, key: str, verify_files: bool = False, whole: bool = False) -> "Checked":
        """What the folder holds under `key`, changing nothing: a Checked whose status is COMPLETE
        (with its done record), MISSING (no done record), OTHER_KEY (one of another key), PRUNED
        (`whole` asked for every frame and some were dropped) or TAMPERED (the record's seal, or with
        `verify_files` a file it lists, does not match: `problem` says which). Removing a tampered
        record is the caller's decision (`invalidate`)."""
        path = folder / "done.json"
        try:
            st = path.stat()
        except FileNotFoundError:
            return Checked(MISSING)
        state = _state(st)
        try:
            got = _RECORDS.get(str(path))
            if got is not None and got[0] == state:
                record = got[1]
            else:
                record = unseal(json.loads(path.read_text()), path)
                if _settled(st):
                    _RECORDS[str(path)] = (state, record)
            if record.get("key") != key:
                return Checked(OTHER_KEY)
            if verify_files:            # the kept files too: a tampered one is reported either way
                for name in record["files"]:
                    self.verify(folder / name, record)
        except (TamperError, ValueError, KeyError, OSError) as exc:
            return Checked(TAMPERED, problem=str(exc))
        return Checked(PRUNED) if whole and record.get("pruned") else Checked(COMPLETE, record)

    def done(self, folder: Path, key: str, verify_files: bool = False, whole: bool = False) -> dict | None:
        """The done record if the folder is complete under `key` (and, if asked, every file intact),
        else None; a tampered one is logged, and left for the caller (`check`, `invalidate`).
        `whole`: only if no file was pruned (the caller needs every frame, not the kept ones)."""
        got = self.check(folder, key, verify_files, whole)
        if got.status == TAMPERED:
            self.log(f"store: {got.problem}; re-making {folder}")
        return got.record

    def prune(self, folder: Path, key: str, keep: set) -> int:
        """Drop the files of a done folder not in `keep` (names): the record first lists only the
        kept ones and names the dropped under 'pruned', then they are deleted. Returns the count."""
        record = self.done(folder, key)
        if record is None:
            return 0
        drop = sorted(n for n in record["files"] if n not in keep)
        if not drop:
            return 0
        _write_done(folder, seal({**record, "files": {n: h for n, h in record["files"].items() if n in keep},
                                  "pruned": sorted(set(record.get("pruned", [])) | set(drop))}))
        for n in drop:
            (folder / n).unlink(missing_ok=True)
        return len(drop)

    def verify(self, path: Path, record: dict) -> None:
        expected = record["files"].get(path.name)
        if expected is None and path.name in record.get("pruned", []):
            raise TamperError(f"{path}: dropped after it was judged (only the frames the report shows are kept)")
        if expected is None:
            raise TamperError(f"{path}: not listed in its done record")
        found = self._sha256(path)
        if found != expected:
            raise TamperError(f"{path}: expected SHA-256 {expected[:16]}, found {found[:16]}")

    def _sha256(self, path: Path) -> str:
        """A file's SHA-256, remembered with its state (inode, size, modification and change time):
        every write sets the change time, which no tool sets back, so a remembered hash is the
        file's own, and a no-op study does not read every kept frame again to check it. A file
        changed in the last 2 s is hashed but not remembered (two writes within one clock tick
        could leave the same state, as git's index knows)."""
        try:
            st = path.stat()
        except FileNotFoundError:
            return "missing"
        state = _state(st)
        memo, name = self._hashes(), self._name(path)
        got = memo.get(name)
        if got is not None and got[:4] == state:
            return got[4]
        sha = sha256_file(path)
        if _settled(st):
            memo[name] = state + [sha]
            _CHANGED.add(str(self.root))
        return sha

    def _name(self, path: Path) -> str:
        try:
            return str(Path(path).relative_to(self.root))
        except ValueError:
            return str(Path(path).resolve())

    def _hashes(self) -> dict:
        root = str(self.root)
        if root not in _HASHES:
            try:
                _HASHES[root] = json.loads((self.root / "file-hashes.json").read_text())
            except (OSError, ValueError):      # none yet, or a damaged one: hash again
                _HASHES[root] = {}
        return _HASHES[root]

    def save_hashes(self) -> None:
        """Keep the remembered hashes of files still there (the next study reads them)."""
        root = str(self.root)
        if root not in _CHANGED or not self.root.is_dir():
            return
        memo = {p: v for p, v in self._hashes().items() if (self.root / p).exists()}
        try:
            write_text_atomic(self.root / "file-hashes.json", json.dumps(memo))
        except OSError:     # a memo (a full disk, say): the next study hashes those files again
            return
        _CHANGED.discard(root)

    def read_image(self, folder: Path, name: str, record: dict) -> dict:
        """Channels of one EXR of a done folder, after checking its hash."""
        self.verify(folder / name, record)
        _, ch = read_exr(folder / name)
        return ch

    def invalidate(self, folder: Path, reason: str) -> None:
        """Remove a folder's done record (one found tampered: `reason`), so that every later check
        finds it missing and its artefact is made again."""
        self.log(f"store: {reason}; re-making {folder}")
        (folder / "done.json").unlink(missing_ok=True)

    # -- sealed JSON records ---------------------------------------------------------------------
    def record_path(self, kind: str, scene: str, key: str) -> Path:
        return self.root / kind / scene / f"{key}.json"

    def load_record(self, path: Path, key: str) -> dict | None:
        if not path.exists():
            return None
        try:
            data = unseal(json.loads(path.read_text()), path)
            return data if data.get("key") == key else None
        except (TamperError, ValueError) as exc:     # left in place: save_record replaces it
            self.log(f"store: {exc}; re-making it")
            return None

    def save_record(self, path: Path, key: str, data: dict) -> dict:
        record = seal({**data, "key": key})
        write_text_atomic(path, json.dumps(record, indent=1, default=_json_default))
        return record

    # -- one writer per key ------------------------------------------------------------------------
    def lock(self, key: str, stale_s: float = 60.0, poll_s: float = 0.2):
        """Exclusive work on `key` among every process sharing this cache (also over NFS: exclusive
        create is atomic there). The holder refreshes the file's time; a waiter breaks a lock
        whose time stopped for `stale_s` (its holder died). Re-entrant: the thread that holds
        `key` enters it again at once, and it is released when the outermost entry ends."""
        return lock_file(self.root / "locks" / f"{key}.lock", self.log, stale_s, poll_s)


class LockBusy(RuntimeError):
    """A lock file another live process holds (`lock_file` with `wait=False`)."""

    def __init__(self, path: Path, owner: str):
        host, pid = (owner.split() + ["?", "?"])[:2]
        super().__init__(f"{path} is held by process {pid} on host {host}")
        self.path, self.owner, self.host, self.pid = path, owner, host, pid


@contextlib.contextmanager
def lock_file(path: Path, log=None, stale_s: float = 60.0, poll_s: float = 0.2, wait: bool = True):
    """Hold the lock file `path` (exclusive create; its text names 'host pid thread'), refreshed by a
    heartbeat; a lock whose process on this host is gone, or whose heartbeat stopped for `stale_s`,
    is broken. The thread that holds it enters it again at once. `wait` False: raise LockBusy
    instead of waiting for a live holder."""
    log = log or (lambda msg: print(msg, file=sys.stderr))
    path = Path(path)
    me = f"{socket.gethostname()} {os.getpid()} {threading.get_ident()}"
    held = (str(path.absolute()), me)
    with _HELD_GUARD:
        again = held in _HELD
        if again:
            _HELD[held] += 1
    if again:           # this thread holds it already (two columns of one key): no wait on itself
        try:
            yield
        finally:
            with _HELD_GUARD:
                _HELD[held] -= 1
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666 & ~_umask())
            os.write(fd, me.encode())
            os.close(fd)
            break
        except FileExistsError:
            try:
                owner = path.read_text()
                dead = _dead_owner(owner)
                if dead or time.time() - path.stat().st_mtime > stale_s:
                    why = "its process is gone" if dead else f"no heartbeat for {stale_s:g} s"
                    log(f"store: breaking the lock {path} of {owner!r}: {why}")
                    if path.read_text() == owner:
                        path.unlink(missing_ok=True)
                    continue
            except FileNotFoundError:
                continue
            if not wait:
                raise LockBusy(path, owner) from None
            time.sleep(poll_s)
    stop = threading.Event()

    def heartbeat():
        while not stop.wait(stale_s / 4):
            with contextlib.suppress(OSError):
                os.utime(path)
    beat = threading.Thread(target=heartbeat, daemon=True)
    beat.start()
    with _HELD_GUARD:
        _HELD[held] = 1
    try:
        yield
    finally:
        with _HELD_GUARD:
            del _HELD[held]
        stop.set()
        beat.join()
        with contextlib.suppress(OSError):
            if path.read_text() == me:
                path.unlink()
