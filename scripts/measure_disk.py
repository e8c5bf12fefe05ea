"""Bytes a pixel each kind of stored file takes, measured on one real frame of a scene:
`PYTHONPATH=. python scripts/measure_disk.py SCENE [--t T] [--size 1600x900] [--bound 8]`.

It renders the scene's reference at instant T (into a temporary reference cache, at the given
per-pixel bound: a reference's size hardly moves with the bound, its noise channels being as
noisy), one raster frame (No AA's, the least smooth a run keeps), that frame's SSIM/FLIP maps
against the reference, and its 8-bit display image, and writes each as the cache does
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
        start = time.time()
        ref, _ = ReferenceCache(tmp / "cache").get(scene, args.t, w, h, se_bound_lsb=args.bound)
        out["reference_s"] = round(time.time() - start, 1)
        path = next((tmp / "cache" / "references").rglob("*.exr"))
        header, ch = read_exr(path)
        out["reference_kept"] = round(path.stat().st_size / px, 2)       # what the cache wrote ('smallest')
        for name in ("zip", "zstd"):
            write_exr(tmp / f"ref_{name}.exr", ch, compression=name)
            out[f"reference_{name}"] = round((tmp / f"ref_{name}.exr").stat().st_size / px, 2)
        r = Rasterizer(scene, w, h)
        try:
            frame = r.render(args.t, (0.0, 0.0), ["color"])["color"][..., :3].astype(np.float32)
        finally:
            r.close()
        disp = DisplayTransform.from_reference(ref.image)
        x_lin, x_disp, x8 = disp.output(frame, "linear")
        refs = [(*r, {}) for r in judged_references(ref, disp).values()]
        (_, maps), = M.all_metrics_against(refs[:1], x_lin, x_disp, x8, want_maps=[True])
        wr = FolderWriter(tmp / "run")
        wr.add("frame_0000.exr", frame)
        wr.add("maps_0000.exr", maps)
        wr.add_png("shown_0000.png", x8)
        assert codec("maps_0000.exr") == "zstd"
        for kind, name in (("frame", "frame_0000.exr"), ("maps", "maps_0000.exr"), ("shown_png", "shown_0000.png")):
            out[kind] = round((tmp / "run" / name).stat().st_size / px, 2)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
