"""The peak memory of one run task's techniques on a static test, against what `estimate` prices:
`PYTHONPATH=. python scripts/measure_run_memory.py SCENE [--steps 32] [--size 1600x900] [--sweep]`.

It runs the thesis profile's ten columns (and with --sweep its 16 sharpen-sweep columns) over a
static schedule of STEPS frames judged at 16 and STEPS, as study.engine.run_task does with `emit`
(each judged image handed on, none kept; nothing judged), and reads the process's resident memory
every 0.2 s. It prints the wall time, the peak RSS and study.engine.estimate.run_memory's figure for
the same frames and columns (docs/performance.md, "Memory").
"""
from __future__ import annotations

import argparse
import os
import threading
import time

COLUMNS = ["No AA=noaa", "FXAA=fxaa", "SMAA=smaa", "Uncharted=taa_baseline", "Improved=taa_improved",
           "Improved, no sharpen=taa_improved:sharpen=none", "Uncharted, no sharpen=taa_baseline:sharpen=none",
           "Uncharted, normalised sharpen=taa_baseline:sharpen=normalised",
           "Improved, Xu sharpen=taa_improved:sharpen=xu", "Accumulation 128=accumulation"]
SWEEP = (0, 0.0625, 0.125, 0.25, 0.375, 0.5, 0.75, 1)


def _rss() -> int:
    with open(f"/proc/{os.getpid()}/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) * 1024
    return 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--steps", type=int, default=32)
    ap.add_argument("--size", default="1600x900")
    ap.add_argument("--sweep", action="store_true", help="add the 16 sharpen-sweep columns")
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.lower().split("x"))

    from display import DisplayTransform
    from raster import Rasterizer
    from shading.mips import has_trilinear
    from study.config.protocols import static_schedule
    from study.config.techniques import TechniqueConfig
    from study.engine.drive import run_schedule
    from study.engine.estimate import raster_frames, run_memory
    from study.engine.tasks import load_scene

    scene = load_scene(a.scene)
    specs = COLUMNS + ([f"{n} w={s}={t}:sharpen={s}" for s in SWEEP
                        for n, t in (("Uncharted", "taa_baseline"), ("Improved", "taa_improved"))] if a.sweep else [])
    configs = [TechniqueConfig.parse(s) for s in specs]
    r = Rasterizer(scene, w, h)
    try:      # FXAA and SMAA work on the display image: a transform from the centre frame
        disp = {0: DisplayTransform.from_reference(r.render(0, (0.0, 0.0), ("color",), prev_t=0)["color"])}
    finally:
        r.close()
    schedule = static_schedule(0, a.steps, sorted({min(16, a.steps), a.steps}))

    peak, done = [0], threading.Event()

    def watch():
        while not done.is_set():
            peak[0] = max(peak[0], _rss())
            time.sleep(0.2)
    threading.Thread(target=watch, daemon=True).start()
    t0 = time.perf_counter()
    run_schedule(scene, w, h, schedule, configs, disp, progress=False, emit=lambda *_: None)
    seconds = time.perf_counter() - t0
    done.set()
    peak[0] = max(peak[0], _rss())

    frames, buffers = raster_frames(schedule, configs, w, h, has_trilinear(scene))
    model = run_memory(w, h, frames, buffers, len(configs))
    print(f"{a.scene} {w}x{h}, {len(configs)} columns, {a.steps} steps: {seconds:.1f} s, peak RSS "
          f"{peak[0] / 1e9:.2f} GB; estimate.run_memory {model / 1e9:.2f} GB ({len(frames)} kept frames)")


if __name__ == "__main__":
    main()
