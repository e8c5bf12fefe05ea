"""Bytes a pixel each kind of stored file takes, measured on one real frame of a scene:
`PYTHONPATH=. python scripts/measure_disk.py SCENE [--t T] [--size 1600x900] [--bound 8]
[--frames-only]`.

It renders the scene's reference at instant T (into a temporary reference cache, at the given
per-pixel bound: a reference's size hardly moves with the bound, its noise channels being as
noisy), one raster frame (No AA's) and the mean of 8 jittered ones (as smooth as a TAA's output),
their SSIM/FLIP maps against the reference and their 8-bit display images, and writes each as the
cache does
(study.engine.store, references.cache): the figures study.engine.disk takes (docs/performance.md,
"Disk").
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("--t", type=int, default=0)
    ap.add_argument("--size", default="1600x900")
    ap.add_argument("--bound", type=float, default=8.0, help="the reference's per-pixel bound, LSB")
    ap.add_argument("--frames-only", action="store_true",
                    help="no reference (its display transform from the frames): the run frames' sizes alone")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.split("x"))

    from display import DisplayTransform
    from raster import Rasterizer
    from references import ReferenceCache
    from references.exr import read_exr, write_exr
    from study.engine.judge import judged_references
    from study.engine.store import FolderWriter, codec
    from study.engine.tasks import load_scene
    from study.metrics import judging as M

    scene = load_scene(args.scene)
    px = w * h
    out = {"scene": scene.name, "t": args.t, "size": [w, h]}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        r = Rasterizer(scene, w, h)
        try:      # one frame (No AA's) and the mean of 8 jittered ones (a TAA's output is as smooth)
            frames = [r.render(args.t, (j / 8 - 0.44, ((3 * j) % 8) / 8 - 0.44), ["color"])["color"][..., :3]
                      .astype(np.float32) for j in range(8)]
        finally:
            r.close()
        wr = FolderWriter(tmp / "run")
        ref = None
        if not args.frames_only:
            start = time.time()
            ref, _ = ReferenceCache(tmp / "cache").get(scene, args.t, w, h, se_bound_lsb=args.bound)
            out["reference_s"] = round(time.time() - start, 1)
            path = next((tmp / "cache" / "references").rglob("*.exr"))
            header, ch = read_exr(path)
            out["reference_kept"] = round(path.stat().st_size / px, 2)       # what the cache wrote ('smallest')
            for name in ("zip", "zstd"):
                write_exr(tmp / f"ref_{name}.exr", ch, compression=name)
                out[f"reference_{name}"] = round((tmp / f"ref_{name}.exr").stat().st_size / px, 2)
        mean = np.mean(frames, axis=0).astype(np.float32)
        disp = DisplayTransform.from_reference(mean if ref is None else ref.image)
        for stem, frame in (("frame", frames[0]), ("frame_mean8", mean)):
            x_lin, x_disp, x8 = disp.output(frame, "linear")
            wr.add(f"{stem}.exr", frame)
            wr.add_png(f"{stem}.png", x8)
            out[stem] = round((tmp / "run" / f"{stem}.exr").stat().st_size / px, 2)
            out[f"{stem}_png"] = round((tmp / "run" / f"{stem}.png").stat().st_size / px, 2)
            if ref is not None:
                refs = [(*r, {}) for r in judged_references(ref, disp).values()]
                (_, maps), = M.all_metrics_against(refs[:1], x_lin, x_disp, x8, want_maps=[True])
                wr.add(f"maps_{stem}.exr", maps)
                assert codec(f"maps_{stem}.exr") == "zstd"
                out[f"maps_{stem}"] = round((tmp / "run" / f"maps_{stem}.exr").stat().st_size / px, 2)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
