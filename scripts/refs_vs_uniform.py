"""Adaptive reference against a uniform high-spp Mitsuba reference of the same frame:
where does the adaptive one miss sub-pixel structure?

Per scene prints seconds and mean spp of the adaptive reference, the display PSNR between the two,
the fraction of pixels within 0.5 LSB + 3.5 sigma (sigma: both references' own SE), the count over
2 LSB, the max |difference| in LSB and the spp of the worst pixel. Direct transports only.

    .venv/bin/python scripts/refs_vs_uniform.py [--size 320x180] [--passes 16] [--spp 256] SCENE ...
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from backend import mi  # noqa: E402
from display import DisplayTransform  # noqa: E402
from references import ReferenceCache  # noqa: E402
from references.mitsuba_scene import SharedShadingIntegrator, sensor  # noqa: E402
from scenes import get_scene  # noqa: E402
from shading import frame_geometry  # noqa: E402

LSB = 1 / 255


def uniform(scene, w, h, passes, spp, seed=7000):
    geo, cam = frame_geometry(scene, 0), scene.camera(0, w, h)
    integ, sens = SharedShadingIntegrator(geo, cam.position), sensor(cam, spp)
    return np.stack([np.asarray(mi.render(geo.mitsuba, sensor=sens, integrator=integ, seed=seed + k, spp=spp),
                                np.float64) for k in range(passes)])


def compare(ad, passes):
    uni = passes.mean(0)
    disp = DisplayTransform.from_reference(uni)
    enc = np.stack([disp.encode(p) for p in passes])
    se_u = enc.std(0, ddof=1) / np.sqrt(len(passes))
    d = np.abs(disp.encode(ad.image) - disp.encode(uni))
    noise = np.sqrt(ad.display_stderr.astype(np.float64) ** 2 + se_u ** 2 + 1e-12)
    excess = (d - 0.5 * LSB - 3.5 * noise).max(-1)
    mse = float(np.mean((disp.encode(ad.image) - disp.encode(uni)) ** 2))
    return d.max(-1) / LSB, excess, 10 * np.log10(1 / mse), se_u.max(-1) / LSB


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--passes", type=int, default=16)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--pilot-spp", type=int, help="spp_per_pass of the adaptive pilot (the cache's default if omitted)")
    args = ap.parse_args()
    w, h = map(int, args.size.split("x"))
    print(f"{'scene':22s} {'ref s':>6s} {'mean spp':>8s} {'PSNR dB':>8s} {'within':>8s} {'>2LSB':>6s} "
          f"{'max LSB':>8s} {'spp@max':>7s} {'uni SE p99.9':>12s}", flush=True)
    tmp = tempfile.mkdtemp(prefix="refs_vs_uniform_")
    for name in args.scenes:
        scene = get_scene(name)
        t0 = time.perf_counter()
        kw = {} if args.pilot_spp is None else {"spp_per_pass": args.pilot_spp}
        ad = ReferenceCache(tmp).get(scene, 0, w, h, **kw)[0]
        sec = time.perf_counter() - t0
        dl, excess, db, seu = compare(ad, uniform(scene, w, h, args.passes, args.spp))
        worst = np.unravel_index(np.argmax(dl), dl.shape)
        print(f"{name:22s} {sec:6.1f} {ad.spp_mean:8.1f} {db:8.2f} {np.mean(excess <= 0):8.5f} "
              f"{int(np.sum(dl > 2)):6d} {dl.max():8.2f} {int(ad.spp_map[worst]):7d} "
              f"{np.percentile(seu, 99.9):12.3f}", flush=True)


if __name__ == "__main__":
    main()
