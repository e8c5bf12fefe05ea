"""Content-addressed cache of references as float32 OpenEXR.

The key hashes everything that determines the image: the scene's content hash (description,
meshes, textures), the frame, the camera state, the resolution, the convergence settings and the
source of the shading and reference code. Files are written atomically (references/exr.py), so an
interrupted render leaves nothing; a file that fails to read, lacks its key or holds NaN/Inf is
reported, removed and rendered again.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np

from scenes import ResolvedScene

from .exr import read_exr, write_exr
from .render import Reference, render_reference

_CODE_FILES = ("shading/surface.py", "shading/frame.py", "references/render.py",
               "references/mitsuba_scene.py")


def default_cache_dir() -> Path:
    return Path(os.environ.get("TAA_STUDY_CACHE", Path.cwd() / ".cache" / "taa-study"))


def code_version() -> str:
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for rel in _CODE_FILES:
        h.update((root / rel).read_bytes())
    return h.hexdigest()[:12]


class ReferenceCache:
    def __init__(self, root: Path | str | None = None, log=None):
        self.root = Path(root) if root is not None else default_cache_dir()
        self.log = log or (lambda msg: print(msg, file=sys.stderr))

    def key(self, scene: ResolvedScene, t: int, width: int, height: int, **settings) -> str:
        cam = scene.camera(t, width, height)
        blob = json.dumps({"scene": scene.content_hash, "frame": t, "width": width, "height": height,
                           "camera": np.round(cam.to_world, 12).tolist(), "fov": cam.yfov_deg,
                           "near": cam.near, "far": cam.far, "settings": settings,
                           "code": code_version()}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:24]

    def path(self, scene: ResolvedScene, key: str) -> Path:
        return self.root / "references" / scene.name / f"{key}.exr"

    def _read(self, path: Path, key: str, shape) -> Reference | None:
        try:
            h, ch = read_exr(path)
            if h.get("taa_key") != key:
                raise ValueError(f"header key {h.get('taa_key')!r} != {key!r}")
            img = np.stack([ch[c] for c in "RGB"], -1).astype(np.float32)
            se = np.stack([ch[f"stderr.{c}"] for c in "RGB"], -1).astype(np.float32)
            if img.shape != shape or not (np.all(np.isfinite(img)) and np.all(np.isfinite(se))):
                raise ValueError("wrong shape or NaN/Inf pixels")
            ref = Reference(img, se, int(h["taa_spp"]), int(h["taa_passes"]), float(h["taa_seconds"]),
                            float(h["taa_noise_psnr_db"]), key)
            ref._history = [tuple(x) for x in json.loads(h.get("taa_convergence", "[]"))]
            return ref
        except Exception as exc:
            self.log(f"reference cache: {path} is corrupt ({exc}); removing it and rendering again")
            path.unlink(missing_ok=True)
            return None

    def _write(self, path: Path, ref: Reference, scene: ResolvedScene, t: int) -> None:
        header = {"taa_key": ref.key, "taa_scene": scene.name, "taa_scene_hash": scene.content_hash,
                  "taa_frame": int(t), "taa_spp": int(ref.spp), "taa_passes": int(ref.passes),
                  "taa_seconds": float(ref.seconds), "taa_noise_psnr_db": float(ref.noise_psnr_db),
                  "taa_code": code_version(),
                  "taa_convergence": json.dumps([[int(a), round(float(b), 4), round(float(c), 3)]
                                                 for a, b, c in ref.noise_history])}
        chans = {"RGB": ref.image}
        for k, c in enumerate("RGB"):
            chans[f"stderr.{c}"] = ref.stderr[..., k]
        write_exr(path, chans, header)

    def get(self, scene: ResolvedScene, t: int, width: int, height: int, *, target_noise_db=60.0,
            spp_per_pass=64, progress=None) -> tuple[Reference, bool]:
        """(reference, was_cached)."""
        key = self.key(scene, t, width, height, target=target_noise_db, spp_per_pass=spp_per_pass)
        path = self.path(scene, key)
        if path.exists():
            ref = self._read(path, key, (height, width, 3))
            if ref is not None:
                return ref, True
        ref = render_reference(scene, t, width, height, target_noise_db=target_noise_db,
                               spp_per_pass=spp_per_pass, progress=progress)
        ref.key = key
        self._write(path, ref, scene, t)
        return ref, False
