"""Content-addressed cache of references as float32 OpenEXR.

The key (`reference_key`, the one place it is made) hashes everything that determines the image:
the scene's content hash (description, meshes, textures), the frame, the camera state, the
resolution, the convergence settings and the source of the shading, reference and display code
(the stopping rule measures noise through the display transform). Each EXR carries the image,
the linear standard error (`stderr.R/G/B`), the display-domain standard error
(`display_stderr.R/G/B`, 1 = full scale), the part of it that is the unseen-feature floor
(`display_floor.R/G/B`, references/render.py), the split into two independent halves
(`half_delta.R/G/B`: half A = RGB + delta, half B = RGB - delta) and the samples per pixel traced (`spp`), and its header
the bound, seconds, mean/max spp, 99.9th percentile and max SE in LSB, the pixels over the bound
(and the samples the worst of them would take), those whose SE is the floor, and whether the value is
the mean of held-out samples (`taa_held_out`, references.estimates: part of the key too). Files are written atomically (references/exr.py), so an
interrupted render leaves nothing; a file that fails to read, lacks its key or holds NaN/Inf is
reported, removed and rendered again.

With `reuse` (references.reuse; true, or the names of the scenes it is on for), frame t's reference
keeps frame t - 1's estimate (at the same settings) where no moving object nor its shadow reaches: its key then hashes frame t - 1's key
(`reuse_from`, itself chained back to frame `reuse_since`, the last frame rendered whole), so no
reference is ever read for a chain it was not derived from; each pixel's smallest and largest
sample (`sample_lo.R/G/B`, `sample_hi.R/G/B`: what the next frame's unseen-feature floor reads)
and which pixels were kept (`reused`) are stored with it. Only then, and beside it, in its own file
(`<key>.extremes.exr`): nothing but the next frame's render reads the extremes, and they are the
noisiest channels (18 of a 1600x900 sphere_ghosting reference's 42 bytes a pixel), so they are
deleted once that frame is made from them. A reference whose extremes are gone (or first rendered
without reuse) is no source for the next frame, which is then rendered whole and starts the chain:
its estimate is as unbiased, not the same bits (a study that removes what it no longer reads,
study.engine.supersede, then needs that frame again only if it removed it).

Each reference also files the display transform its image gives (`<key>.display.json`,
display.DisplayTransform.from_reference: two numbers): a study's display transforms come from its
probe references (study.engine.tasks.display_of), which it may then remove once it has refined
past them (study.engine.supersede) without rendering them again for the transform.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np

from scenes import ResolvedScene

from . import settings as S
from .exr import read_exr, write_exr
from .render import render_reference
from .result import Reference
from .reuse import global_change

_CODE_FILES = ("shading/surface.py", "shading/frame.py", "references/render.py", "references/estimates.py",
               "references/settings.py", "references/reuse.py",
               "references/tracer.py", "references/mitsuba_scene.py", "display/__init__.py")


def default_cache_dir() -> Path:
    return Path(os.environ.get("TAA_STUDY_CACHE", Path.cwd() / ".cache" / "taa-study"))


def code_version(root: Path | None = None) -> str:
    root = Path(root) if root is not None else Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for rel in _CODE_FILES:
        h.update((root / rel).read_bytes())
    return h.hexdigest()[:12]


def reference_key(scene: ResolvedScene, t: int, width: int, height: int, *, code: str | None = None,
                  **settings) -> str:
    """The content key of one reference: scene content, frame, camera, resolution, settings, code
    (a reused-reference frame's settings hold `reuse_from`, the key of the frame it keeps pixels of)."""
    cam = scene.camera(t, width, height)
    blob = json.dumps({"scene": scene.content_hash, "frame": t, "width": width, "height": height,
                       "camera": np.round(cam.to_world, 12).tolist(), "fov": cam.yfov_deg,
                       "near": cam.near, "far": cam.far, "settings": settings,
                       "code": code or code_version()}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:24]


def reuse_on(name: str, reuse) -> bool:
    """Whether the setting `reuse` (true, false, or the names of the scenes it is on for) is on for
    the scene `name`."""
    return reuse is True or (isinstance(reuse, (list, tuple)) and name in reuse)


def reuses(scene: ResolvedScene, t: int, width: int, height: int, reuse, reuse_since: int) -> bool:
    """Whether frame t's reference keeps pixels of frame t - 1's (references.reuse.global_change)."""
    return reuse_on(scene.name, reuse) and t > max(int(reuse_since), 0) and global_change(scene, t, width, height) is None


class ReferenceCache:
    def __init__(self, root: Path | str | None = None, log=None):
        self.root = Path(root) if root is not None else default_cache_dir()
        self.log = log or (lambda msg: print(msg, file=sys.stderr))

    def key(self, scene: ResolvedScene, t: int, width: int, height: int, *, reuse: bool = False,
            reuse_since: int = 0, **settings) -> str:
        """The cache key; a frame that reuses frame t - 1's pixels hashes that frame's key, and so
        on back to `reuse_since` (or the last frame that reuses nothing)."""
        return self.chain(scene, t, width, height, reuse=reuse, reuse_since=reuse_since, **settings)[-1]

    def chain(self, scene: ResolvedScene, t: int, width: int, height: int, *, reuse: bool = False,
              reuse_since: int = 0, memo: dict | None = None, **settings) -> list[str]:
        """The keys of the references frame t's is made from, the chain's first frame's to its own
        (one key where it reuses nothing). `memo`: keys already found, shared by the calls for one
        chain's instants (each walks back to where an earlier one's chain starts)."""
        memo = {} if memo is None else memo
        code = code_version()
        kind = (scene.content_hash, width, height, reuse, reuse_since, repr(sorted(settings.items())))
        first = t
        while reuses(scene, first, width, height, reuse, reuse_since):
            if ("first", *kind, first - 1) in memo:        # where an earlier instant's chain starts
                first = memo[("first", *kind, first - 1)]
                break
            first -= 1
        memo[("first", *kind, t)] = first
        out, key = [], None
        for s in range(first, t + 1):
            m = (*kind, s, key)
            if m not in memo:
                memo[m] = reference_key(scene, s, width, height, code=code, **settings,
                                        **({} if key is None else {"reuse_from": key}))
            key = memo[m]
            out.append(key)
        return out

    def path(self, scene: ResolvedScene, key: str) -> Path:
        return self.root / "references" / scene.name / f"{key}.exr"

    def settings_key(self, scene: ResolvedScene, t: int, width: int, height: int, **settings) -> str:
        """The key of the reference `get` returns for these settings (`get`'s names)."""
        return self.settings_chain(scene, t, width, height, **settings)[-1]

    def settings_chain(self, scene: ResolvedScene, t: int, width: int, height: int, *, se_bound_lsb=S.SE_BOUND_LSB,
                       target_noise_db=S.TARGET_NOISE_DB, spp_per_pass=2, held_out=False, reuse=False,
                       reuse_since=0, memo: dict | None = None) -> list[str]:
        """`chain` for `get`'s settings: the keys of every reference frame t's is made from."""
        return self.chain(scene, t, width, height, bound_lsb=se_bound_lsb, target=target_noise_db,
                          spp_per_pass=spp_per_pass, held_out=bool(held_out), reuse=reuse, reuse_since=reuse_since,
                          memo=memo)

    def display(self, scene: ResolvedScene, t: int, width: int, height: int, **settings):
        """(key, display.DisplayTransform) of the reference `get` would return for these settings:
        from its display record where filed (the reference itself may be gone), else from the
        reference (rendered if missing), its record filed then."""
        key = self.settings_key(scene, t, width, height, **settings)
        got = read_display(self.path(scene, key), key)
        if got is not None:
            return key, got
        ref = self.get(scene, t, width, height, **settings)[0]
        disp = write_display(self.path(scene, key), key, ref.image)
        return key, disp

    def has_display(self, scene: ResolvedScene, t: int, width: int, height: int, **settings) -> bool:
        """Whether `display` needs no render: the display record or the reference is in the cache."""
        path = self.path(scene, self.settings_key(scene, t, width, height, **settings))
        return display_path(path).exists() or path.exists()

    def _read(self, path: Path, key: str, shape) -> Reference | None:
        try:
            h, ch = read_exr(path)
            if h.get("taa_key") != key:
                raise ValueError(f"header key {h.get('taa_key')!r} != {key!r}")
            img = np.stack([ch[c] for c in "RGB"], -1).astype(np.float32)
            se = np.stack([ch[f"stderr.{c}"] for c in "RGB"], -1).astype(np.float32)
            dse = np.stack([ch[f"display_stderr.{c}"] for c in "RGB"], -1).astype(np.float32)
            spp = ch["spp"].astype(np.int32)
            floor = np.stack([ch[f"display_floor.{c}"] for c in "RGB"], -1).astype(np.float32)
            half = np.stack([ch[f"half_delta.{c}"] for c in "RGB"], -1).astype(np.float32)
            if img.shape != shape or not all(np.all(np.isfinite(x)) for x in (img, se, dse, half)):
                raise ValueError("wrong shape or NaN/Inf pixels")
            history = [tuple(x) for x in json.loads(h.get("taa_convergence", "[]"))]
            extra = {}
            side = extremes_path(path)
            if "sample_lo.R" not in ch and side.exists():   # the extremes, kept beside it until the next frame is made
                sh, sch = read_exr(side)
                if sh.get("taa_key") != key:
                    raise ValueError(f"{side.name}: header key {sh.get('taa_key')!r} != {key!r}")
                ch = {**ch, **sch}
            if "sample_lo.R" in ch:       # (written inside the reference by earlier versions)
                extra = {f"sample_{n}": np.stack([ch[f"sample_{n}.{c}"] for c in "RGB"], -1).astype(np.float32)
                         for n in ("lo", "hi")}
            if "reused" in ch:
                extra["reused"] = ch["reused"] > 0.5
            return Reference(img, se, int(h["taa_spp"]), int(h["taa_passes"]), float(h["taa_seconds"]),
                             float(h["taa_noise_psnr_db"]), key, spp_map=spp, display_stderr=dse,
                             bound_lsb=float(h["taa_bound_lsb"]), rounds=int(h["taa_rounds"]), _history=history,
                             display_floor=floor, half_delta=half, spp_needed=int(h.get("taa_spp_needed", 0)),
                             held_out=h.get("taa_held_out") == "1", **extra)
        except Exception as exc:
            self.log(f"reference cache: {path} is corrupt ({exc}); removing it and rendering again")
            path.unlink(missing_ok=True)
            return None

    def _write(self, path: Path, ref: Reference, scene: ResolvedScene, t: int, extremes: bool = True) -> None:
        header = {"taa_key": ref.key, "taa_scene": scene.name, "taa_scene_hash": scene.content_hash,
                  "taa_frame": int(t), "taa_spp": int(ref.spp), "taa_passes": int(ref.passes),
                  "taa_rounds": int(ref.rounds), "taa_seconds": float(ref.seconds),
                  "taa_noise_psnr_db": float(ref.noise_psnr_db), "taa_bound_lsb": float(ref.bound_lsb),
                  "taa_spp_mean": float(ref.spp_mean), "taa_spp_max": int(ref.spp_max),
                  "taa_se_p999_lsb": float(ref.se_p999_lsb), "taa_se_max_lsb": float(ref.se_max_lsb),
                  "taa_over_bound": int(ref.over_bound), "taa_floor_bound": int(ref.floor_bound),
                  "taa_spp_needed": int(ref.spp_needed), "taa_held_out": "1" if ref.held_out else "0",
                  "taa_code": code_version(), "taa_traced": int(ref.traced),
                  "taa_reused": int(0 if ref.reused is None else ref.reused.sum()),
                  "taa_convergence": json.dumps([[int(round(a)), round(float(b), 4), round(float(c), 3),
                                                  round(float(d), 3)] for a, b, c, d in ref.noise_history])}
        chans, side = {"RGB": ref.image, "spp": ref.spp_map}, {}
        for k, c in enumerate("RGB"):
            chans[f"stderr.{c}"] = ref.stderr[..., k]
            chans[f"display_stderr.{c}"] = ref.display_stderr[..., k]
            chans[f"display_floor.{c}"] = ref.display_floor[..., k]
            chans[f"half_delta.{c}"] = ref.half_delta[..., k]
            if ref.sample_lo is not None and extremes:      # a source of the next frame's reuse
                side[f"sample_lo.{c}"], side[f"sample_hi.{c}"] = ref.sample_lo[..., k], ref.sample_hi[..., k]
        if ref.reused is not None:
            chans["reused"] = ref.reused.astype(np.float32)
        if side:        # first: a reference found has its extremes (a stray one alone is ignored)
            # read once, by the next frame, then removed: the faster codec, not the smaller file
            write_exr(extremes_path(path), side, {"taa_key": ref.key}, compression="zstd")
        # Zstandard: smaller than ZIP on the 1600x900 references measured (hairball_rotating_unlit 14.5
        # against 15.0 MB, sphere_ghosting 34.1 against 53.4) and no slower; trying both cost 0.6-1.6 s
        write_exr(path, chans, header, compression="zstd")
        write_display(path, ref.key, ref.image)      # last: a record stands for a reference written whole

    def has(self, scene: ResolvedScene, t: int, width: int, height: int, *, se_bound_lsb=S.SE_BOUND_LSB,
            target_noise_db=S.TARGET_NOISE_DB, spp_per_pass=2, held_out=False, reuse=False, reuse_since=0) -> bool:
        """Whether the reference `get` would return is in the cache (not verified)."""
        return self.path(scene, self.settings_key(scene, t, width, height, se_bound_lsb=se_bound_lsb,
                                                  target_noise_db=target_noise_db, spp_per_pass=spp_per_pass,
                                                  held_out=held_out, reuse=reuse, reuse_since=reuse_since)).exists()

    def get(self, scene: ResolvedScene, t: int, width: int, height: int, *, se_bound_lsb=S.SE_BOUND_LSB,
            target_noise_db=S.TARGET_NOISE_DB, spp_per_pass=2, held_out=False, reuse=False, reuse_since=0,
            progress=None) -> tuple[Reference, bool]:
        """(reference, was_cached): every pixel's display-domain SE <= se_bound_lsb (8-bit LSB)
        and the mean noise >= target_noise_db, or the pixels that hit the sample cap counted.
        `reuse`: keep frame t - 1's estimate (at these settings, got from here: rendered first if
        missing) where references.reuse finds nothing changes, back to frame `reuse_since`."""
        key = self.settings_key(scene, t, width, height, se_bound_lsb=se_bound_lsb, target_noise_db=target_noise_db,
                                spp_per_pass=spp_per_pass, held_out=held_out, reuse=reuse, reuse_since=reuse_since)
        path = self.path(scene, key)
        if path.exists():
            ref = self._read(path, key, (height, width, 3))
            if ref is not None:
                return ref, True
        prev = None
        if reuses(scene, t, width, height, reuse, reuse_since):
            prev = self.get(scene, t - 1, width, height, se_bound_lsb=se_bound_lsb, target_noise_db=target_noise_db,
                            spp_per_pass=spp_per_pass, held_out=held_out, reuse=reuse, reuse_since=reuse_since)[0]
            if prev.sample_lo is None:       # written before extremes were stored: cannot be a source
                prev = None
        ref = render_reference(scene, t, width, height, se_bound_lsb=se_bound_lsb,
                               target_noise_db=target_noise_db, spp_per_pass=spp_per_pass, held_out=bool(held_out),
                               progress=progress, reuse_from=prev)
        ref.key = key
        self._write(path, ref, scene, t, extremes=reuse_on(scene.name, reuse))
        if prev is not None:     # its extremes made this frame: read by nothing else
            extremes_path(self.path(scene, prev.key)).unlink(missing_ok=True)
        return ref, False


def extremes_path(path: Path) -> Path:
    """Where the sample extremes of the reference at `path` are kept until the next frame is made."""
    return path.with_name(path.stem + ".extremes.exr")


def display_path(path: Path) -> Path:
    """The display record of the reference at `path`."""
    return path.with_name(path.stem + ".display.json")


def write_display(path: Path, key: str, image: np.ndarray):
    """File the display transform of the reference image (key `key`) at `path`; returns it."""
    from display import DisplayTransform
    disp = DisplayTransform.from_reference(image)
    rec, out = display_path(path), {"taa_key": key, **dataclasses.asdict(disp)}
    rec.parent.mkdir(parents=True, exist_ok=True)
    tmp = rec.with_name(f".{rec.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(out, sort_keys=True))
    os.replace(tmp, rec)
    return disp


def read_display(path: Path, key: str):
    """The display transform filed beside the reference at `path` (its key `key`), or None."""
    from display import DisplayTransform
    try:
        rec = json.loads(display_path(path).read_text())
        if rec.pop("taa_key") != key:
            return None
        disp = DisplayTransform(**rec)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    vals = [float(v) for v in dataclasses.asdict(disp).values()]
    return disp if all(np.isfinite(v) and v > 0 for v in vals) else None
