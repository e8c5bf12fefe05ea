"""How much of a scene's first raster frame is Dr.Jit kernel compilation, and whether a second
scene reuses the first one's kernels (what varies per scene in them).

    HOME=$(mktemp -d) .venv/bin/python scripts/first_frame_compile.py [--scenes pipe,atrium,flowers] [--size 320x180]

Run it with an empty HOME (no ~/.drjit disk cache) for a new machine's figures, again with the same
HOME for a warm disk cache. Per scene, in one process, in order: the first frame (t=0), a second
jitter at the same instant and frame 1; for each the wall ms, the kernels launched, how many were
compiled (not in this process's memory cache), how many of those came from the disk cache, and the
codegen + backend (LLVM) ms of the compiled ones.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="pipe,atrium,flowers")
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--buffers", default="color,depth,motion")
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    import backend  # noqa: F401  (libLLVM first)
    from backend import dr
    from raster import Rasterizer
    from scenes import get_scene
    from scenes.jitter import halton_offset

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    bufs = tuple(a.buffers.split(","))
    print(f"{'scene':14s} {'frame':22s} {'ms':>8s} {'kernels':>8s} {'compiled':>9s} {'from disk':>9s} {'compile ms':>10s}")
    for name in a.scenes.split(","):
        scene = get_scene(name)
        t0 = time.perf_counter()
        r = Rasterizer(scene, w, h)
        setup_ms = 1000 * (time.perf_counter() - t0)
        print(f"{name:14s} {'(rasteriser set-up)':22s} {setup_ms:8.1f}")
        for label, (t, j, prev) in (("t=0, first", (0, halton_offset(1, 16), 0)),
                                    ("t=0, another jitter", (0, halton_offset(2, 16), 0)),
                                    ("t=1", (1, halton_offset(3, 16), 0))):
            dr.kernel_history_clear()
            t0 = time.perf_counter()
            r.render(t, j, bufs, prev_t=prev)
            ms = 1000 * (time.perf_counter() - t0)
            ks = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
            miss = [k for k in ks if not k.get("cache_hit", False)]
            disk = [k for k in miss if k.get("cache_disk", False)]
            comp = sum(k.get("codegen_time", 0.0) + k.get("backend_time", 0.0) for k in miss)
            print(f"{name:14s} {label:22s} {ms:8.1f} {len(ks):8d} {len(miss):9d} {len(disk):9d} {comp:10.1f}")
        r.close()


if __name__ == "__main__":
    main()
