"""Make-style artefact store: every artefact lives under a folder named by the hash of what
produced it, and is complete only once its `done.json` (written last, atomically) names that key.
An interrupted run leaves folders without `done.json`, which are never read back."""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

from references.exr import read_exr, write_exr


def write_text_atomic(path: Path, text: str) -> bool:
    """Write only if the content changed (so untouched artefacts keep their times); True if written."""
    return write_bytes_atomic(path, text.encode())


def write_bytes_atomic(path: Path, data: bytes) -> bool:
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and path.read_bytes() == data:
        return False
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".part")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)
    return True


class RunStore:
    """Outputs of one technique over one protocol run: frame images + done.json."""

    def __init__(self, root: Path):
        self.root = Path(root)

    def folder(self, kind: str, scene: str, key: str) -> Path:
        return self.root / "runs" / kind / scene / key

    def load(self, folder: Path, key: str) -> dict | None:
        done = folder / "done.json"
        if not done.exists():
            return None
        try:
            meta = json.loads(done.read_text())
            if meta.get("key") != key:
                return None
            images = {}
            for t in meta["frames"]:
                _, ch = read_exr(folder / f"frame_{t:04d}.exr")
                images[t] = np.stack([ch[c] for c in "RGB"], -1)
            return {"meta": meta, "images": images}
        except Exception:
            return None   # unreadable: recompute

    def save(self, folder: Path, key: str, images: dict[int, np.ndarray], meta: dict) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "done.json").unlink(missing_ok=True)
        for t, img in images.items():
            write_exr(folder / f"frame_{t:04d}.exr", {"RGB": img})
        write_text_atomic(folder / "done.json", json.dumps({**meta, "key": key, "frames": sorted(images)},
                                                           indent=1))

    def load_json(self, path: Path, key: str) -> dict | None:
        try:
            data = json.loads(path.read_text())
            return data if data.get("key") == key else None
        except Exception:
            return None

    def save_json(self, path: Path, key: str, data: dict) -> None:
        write_text_atomic(path, json.dumps({**data, "key": key}, indent=1, default=_json_default))


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o))
