"""Reference cost on the current Dr.Jit/Mitsuba variant (TAA_VARIANT; default llvm_ad_rgb), for
comparing a GPU (cuda_ad_rgb) with this machine's CPU: one reference frame of a scene at the full
profile's reference settings ([reference] of study/config/profiles/full.toml), cold (the first
render of the process: kernels compiled) then warm (another frame, the kernels reused), rendered
into a temporary cache. `--smoke` instead checks the stack: the variant, a tiny Mitsuba render and
one raster frame (pyrender through EGL) of a scene.

    TAA_VARIANT=cuda_ad_rgb python3 scripts/gpu_bench.py [--scene hairball_rotating_lit]
        [--width 1600 --height 900] [--frames 0 1] [--compare pipe] [--held-out] [--profile thesis]
        [--intersect [--rays-per-pixel 16 --repeats 3]]

`--intersect` then times Mitsuba's own `ray_intersect` on the scene's frame 0 (camera rays, the
reference's geometry) and prints its rays/s beside the reference's samples/s.
    python3 scripts/gpu_bench.py --smoke [--scene pipe --width 320 --height 180]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def smoke(scene_name: str, width: int, height: int) -> None:
    t0 = time.perf_counter()
    import backend
    from backend import dr, mi
    print(f"backend: TAA_VARIANT={backend.VARIANT} mi.variant()={mi.variant()} drjit {dr.__version__} "
          f"mitsuba {mi.__version__} ({time.perf_counter() - t0:.2f} s)", flush=True)
    if mi.variant().startswith("cuda"):
        try:
            print(f"  dr.has_backend(CUDA)={dr.has_backend(dr.JitBackend.CUDA)}", flush=True)
        except Exception as exc:   # noqa: BLE001
            print(f"  dr.has_backend: {exc!r}")
    t0 = time.perf_counter()
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "path"},
                          "sensor": {"type": "perspective",
                                     "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0],
                                                                                up=[0, 1, 0]),
                                     "film": {"type": "hdrfilm", "width": 32, "height": 24}},
                          "emitter": {"type": "constant"},
                          "shape": {"type": "sphere", "bsdf": {"type": "diffuse"}}})
    img = mi.render(scene, spp=16)
    import numpy as np
    arr = np.asarray(img)
    print(f"mitsuba tiny render {arr.shape} mean={arr.mean():.4f} finite={bool(np.isfinite(arr).all())} "
          f"({time.perf_counter() - t0:.2f} s)", flush=True)

    from raster import Rasterizer
    from scenes import get_scene
    t0 = time.perf_counter()
    r = Rasterizer(get_scene(scene_name), width, height)
    out = r.render(0)
    col = np.asarray(out["color"] if isinstance(out, dict) else out[0])
    t1 = time.perf_counter()
    out = r.render(1)
    t2 = time.perf_counter()
    try:
        from OpenGL import GL
        vendor = GL.glGetString(GL.GL_VENDOR)
        renderer = GL.glGetString(GL.GL_RENDERER)
        print(f"GL_VENDOR={vendor!r} GL_RENDERER={renderer!r}")
    except Exception as exc:   # noqa: BLE001
        print(f"GL strings unavailable: {exc!r}")
    print(f"raster {scene_name} {width}x{height}: color {col.shape} mean={col.mean():.4f} "
          f"finite={bool(np.isfinite(col).all())}; frame 0 {t1 - t0:.2f} s (context, shaders, kernels), "
          f"frame 1 {t2 - t1:.3f} s", flush=True)
    r.close()
    print("SMOKE OK", flush=True)


def bench(args) -> float | None:
    t0 = time.perf_counter()
    import backend
    from backend import mi
    from references import ReferenceCache
    from scenes import get_scene
    import tomllib      # the profile's [reference] read directly: loading the profile needs cvvdp's data
    path = Path(__file__).resolve().parent.parent / "study" / "config" / "profiles" / f"{args.profile}.toml"
    settings = dict(tomllib.loads(path.read_text())["reference"])
    if args.bound is not None:
        settings["se_bound_lsb"] = args.bound
    if args.held_out:
        settings["held_out"] = True
    print(f"variant {mi.variant()} (TAA_VARIANT={backend.VARIANT}); import {time.perf_counter() - t0:.2f} s; "
          f"reference settings {settings}", flush=True)
    print(f"{'case':38s} {'wall s':>8s} {'ref s':>8s} {'mean spp':>9s} {'max spp':>8s} {'Msamples':>9s} "
          f"{'Msamples/s':>10s} {'over':>6s} {'noise dB':>8s}", flush=True)
    cases = [(args.scene, t, "cold" if i == 0 else "warm") for i, t in enumerate(args.frames)]
    cases += [(c, 0, "compare") for c in args.compare]
    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        cache = ReferenceCache(tmp)
        for name, t, tag in cases:
            scene = get_scene(name)
            t0 = time.perf_counter()
            ref, cached = cache.get(scene, t, args.width, args.height, **settings)
            wall = time.perf_counter() - t0
            total = float(ref.spp_map.sum())
            print(f"{f'{name} t={t} {args.width}x{args.height} {tag}':38s} {wall:8.2f} {ref.seconds:8.2f} "
                  f"{ref.spp_mean:9.1f} {ref.spp_max:8d} {total / 1e6:9.2f} {total / 1e6 / max(ref.seconds, 1e-9):10.2f} "
                  f"{ref.over_bound:6d} {ref.noise_psnr_db:8.2f}{' (cached!)' if cached else ''}", flush=True)
            if name == args.scene:
                rates[tag] = total / 1e6 / max(ref.seconds, 1e-9)
    return rates.get("warm", rates.get("cold"))


def intersect(args, ref_rate: float | None) -> None:
    """Mitsuba's own ray_intersect rate on the scene's frame 0 (its path-tracing scene, the
    reference's geometry): `--rays-per-pixel` camera rays a pixel at the bench's size, traced
    `--repeats` times after one untimed pass (kernels compiled); the best pass is printed beside
    the reference's samples/s, each of whose samples is a path of several such rays and their shading."""
    from backend import dr, mi
    from references.mitsuba_scene import path_scene, sensor
    from scenes import get_scene
    scene = get_scene(args.scene)
    mscene = path_scene(scene, 0)
    sens = sensor(scene.camera(0, args.width, args.height), 1)
    n = args.width * args.height * args.rays_per_pixel
    rng = dr.arange(mi.UInt32, n)
    pos = mi.Point2f(mi.Float(rng % args.width) + 0.5, mi.Float((rng // args.width) % args.height) + 0.5)
    pos = mi.Point2f(pos.x / args.width, pos.y / args.height)
    ray, _ = sens.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    dr.eval(ray)
    best, hits = None, 0
    for i in range(args.repeats + 1):
        dr.sync_thread()
        t0 = time.perf_counter()
        si = mscene.ray_intersect(mi.Ray3f(ray))
        valid = si.is_valid()
        dr.eval(si.t, valid)
        dr.sync_thread()
        dt = time.perf_counter() - t0
        if i:                              # the first pass compiles the kernel
            best = dt if best is None else min(best, dt)
            hits = int(dr.count(valid)[0]) if hasattr(dr.count(valid), "__getitem__") else int(dr.count(valid))
    rate = n / 1e6 / best
    line = (f"ray_intersect {args.scene} t=0 {args.width}x{args.height}, {args.rays_per_pixel} rays a pixel "
            f"({n / 1e6:.2f} M rays, {hits / n:.1%} hit): best of {args.repeats} {best:.4f} s, {rate:.1f} M rays/s")
    if ref_rate:
        line += f"; the reference's {ref_rate:.2f} M samples/s is {ref_rate / rate:.3%} of it"
    print(line, flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--smoke", action="store_true", help="check the variant, Mitsuba and the EGL raster")
    ap.add_argument("--scene", default=None, help="default: hairball_rotating_lit (bench), pipe (--smoke)")
    ap.add_argument("--width", type=int, default=1600)
    ap.add_argument("--height", type=int, default=900)
    ap.add_argument("--frames", type=int, nargs="+", default=[0, 1],
                    help="scene times: the first cold, the rest warm")
    ap.add_argument("--compare", nargs="*", default=["pipe"], help="scenes rendered after, frame 0")
    ap.add_argument("--profile", default="full", help="the built-in profile whose [reference] is used")
    ap.add_argument("--bound", type=float, default=None, help="override se_bound_lsb")
    ap.add_argument("--held-out", action="store_true", help="held-out references (the figures rule's)")
    ap.add_argument("--intersect", action="store_true",
                    help="then Mitsuba's own ray_intersect rate on the scene (camera rays), beside the reference's")
    ap.add_argument("--rays-per-pixel", type=int, default=16, help="--intersect's rays a pixel")
    ap.add_argument("--repeats", type=int, default=3, help="--intersect's timed passes")
    args = ap.parse_args()
    if args.smoke:
        smoke(args.scene or "pipe", args.width, args.height)
    else:
        args.scene = args.scene or "hairball_rotating_lit"
        rate = bench(args) if args.frames else None
        if args.intersect:
            intersect(args, rate)


if __name__ == "__main__":
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    main()
