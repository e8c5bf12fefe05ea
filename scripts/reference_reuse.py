"""Samples and time that reference reuse across frames saves (references.reuse): one scene's
ghosting frames rendered whole, then as a chain that keeps the previous frame's pixels where no
moving object nor its shadow reaches. Prints per frame the kept fraction, the samples traced and
the seconds, and the totals.

    .venv/bin/python scripts/reference_reuse.py sphere_ghosting --size 320 180 --frames 24 --bound 8
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("--size", type=int, nargs=2, default=(320, 180))
    ap.add_argument("--frames", type=int, default=24, help="frames 0 .. N-1 (the quick profile's ghosting frames)")
    ap.add_argument("--bound", type=float, default=8.0, help="per-pixel bound, LSB (the figures rule's probe: 8)")
    ap.add_argument("--json", help="write the per-frame figures here")
    a = ap.parse_args()
    from references import render_reference
    from references.reuse import reuse_mask
    from study.engine.tasks import load_scene
    scene = load_scene(a.scene)
    w, h = a.size
    kw = dict(se_bound_lsb=a.bound, target_noise_db=0.0, held_out=True)
    n = min(a.frames, scene.desc.frames)
    render_reference(scene, 0, 16, 9, **kw)          # Dr.Jit's kernels compiled outside the timings
    rows, prev = [], None
    for t in range(n):
        t0 = time.perf_counter()
        whole = render_reference(scene, t, w, h, **kw)
        s_whole = time.perf_counter() - t0
        t0 = time.perf_counter()
        kept = render_reference(scene, t, w, h, reuse_from=prev, **kw) if prev is not None else whole
        s_kept = time.perf_counter() - t0 if prev is not None else s_whole
        mask = reuse_mask(scene, t, w, h)
        rows.append({"t": t, "test_kept": None if mask is None else float(mask.mean()),
                     "kept": 0.0 if kept.reused is None else float(kept.reused.mean()),
                     "traced_whole": whole.traced, "traced_reuse": kept.traced,
                     "s_whole": round(s_whole, 3), "s_reuse": round(s_kept, 3),
                     "over_whole": whole.over_bound, "over_reuse": kept.over_bound})
        print(json.dumps(rows[-1]), flush=True)
        prev = kept
    tw, tr = sum(r["traced_whole"] for r in rows), sum(r["traced_reuse"] for r in rows)
    sw, sr = sum(r["s_whole"] for r in rows), sum(r["s_reuse"] for r in rows)
    print(f"{a.scene} {w}x{h} frames 0..{n - 1} at {a.bound} LSB: samples traced {tw} whole, {tr} with reuse "
          f"({100 * (1 - tr / tw):.1f} % saved); {sw:.1f} s whole, {sr:.1f} s with reuse; "
          f"mean kept fraction {np.mean([r['kept'] for r in rows[1:]]):.3f}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
