"""Seconds per metric for one image pair, library (scikit-image, flip-evaluator) against Dr.Jit.

    .venv/bin/python scripts/bench_metrics.py [--width 1600 --height 900] [--exr REFERENCE.exr] [--repeat 3]

The pair: a reference (a cached reference EXR upsampled to the size when --exr is given, else a
synthetic HDR image with edges, gradients and highlights) and a "technique" image (the reference
shifted by one pixel with 5 % multiplicative noise). Times are warm (the first call, which compiles
Dr.Jit's kernels, is excluded) and the best of --repeat calls; wall and process CPU seconds.
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def synthetic(h: int, w: int) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w] / np.float32(max(h, w))
    img = np.stack([0.2 + 0.6 * x, 0.3 + 0.4 * y, 0.5 - 0.3 * x * y], -1)
    img = img * (1 + 0.5 * (np.sin(40 * x + 25 * y) > 0))[..., None]       # hard edges
    for cx, cy, v in ((0.3, 0.2, 3.0), (0.7, 0.4, 1.5), (0.5, 0.5, 0.8)):
        img += v * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 2e-4)[..., None]   # highlights
    return img.astype(np.float32)


def pair(args):
    if args.exr:
        from references.exr import read_exr
        _, ch = read_exr(args.exr)
        ref = np.stack([ch[c] for c in "RGB"], -1).astype(np.float32)
        ry, rx = -(-args.height // ref.shape[0]), -(-args.width // ref.shape[1])
        ref = np.repeat(np.repeat(ref, ry, 0), rx, 1)[:args.height, :args.width]
    else:
        ref = synthetic(args.height, args.width)
    rng = np.random.default_rng(1)
    x = np.maximum(np.roll(ref, 1, axis=1) * (1 + 0.05 * rng.standard_normal(ref.shape)), 0).astype(np.float32)
    return ref, x


def timed(fn, repeat: int):
    fn()
    best_w, best_c = float("inf"), float("inf")
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), cpu()
        fn()
        best_w, best_c = min(best_w, time.perf_counter() - w0), min(best_c, cpu() - c0)
    return best_w, best_c


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=1600)
    ap.add_argument("--height", type=int, default=900)
    ap.add_argument("--exr", help="a reference EXR to upsample (default: a synthetic image)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    if args.width < 16 or args.height < 16 or args.repeat < 1:
        print("bench_metrics: --width and --height must be >= 16 and --repeat >= 1", file=sys.stderr)
        return 2
    if args.exr and not Path(args.exr).is_file():
        print(f"bench_metrics: --exr {args.exr}: no such file", file=sys.stderr)
        return 2

    from display import DisplayTransform
    from study.metrics import flip as F
    from study.metrics import judging as J
    from study.metrics import suite as M

    ref, x = pair(args)
    dt = DisplayTransform.from_reference(ref)
    rd, xd = dt.encode(ref), dt.encode(x)
    r8, x8 = np.round(rd * 255).astype(np.uint8), np.round(xd * 255).astype(np.uint8)
    _, _, n_exp = F.exposures(ref)
    print(f"{args.width}x{args.height}, HDR-FLIP exposures: {n_exp}; seconds, warm, best of {args.repeat}")
    rows = [
        ("ssim", lambda i: M.ssim(r8, x8, i)),
        ("ssim + ssim_volume", None),
        ("flip_ldr", lambda i: M.flip(rd, xd, "LDR", i)),
        ("flip_hdr", lambda i: M.flip(ref, x, "HDR", i)),
        ("all_metrics", lambda i: J.all_metrics(ref, rd, r8, x, xd, x8, impl=i)),
    ]
    print(f"{'metric':<20}{'library wall':>13}{'cpu':>8}{'drjit wall':>12}{'cpu':>8}{'speed-up':>10}")
    for name, fn in rows:
        if fn is None:
            from study.metrics import ssim as S
            lib = None
            new = timed(lambda: S.ssim_both(r8, x8), args.repeat)
        else:
            lib = timed(lambda: fn("library"), args.repeat)
            new = timed(lambda: fn("drjit"), args.repeat)
        lw = f"{lib[0]:13.3f}{lib[1]:8.3f}" if lib else f"{'-':>13}{'-':>8}"
        sp = f"{lib[0] / new[0]:9.1f}x" if lib else f"{'-':>10}"
        print(f"{name:<20}{lw}{new[0]:12.3f}{new[1]:8.3f}{sp}")
    # Agreement at this size (the tests pin it on small images).
    s_lib, m_lib = M.ssim(r8, x8, "library")
    s_new, m_new = M.ssim(r8, x8)
    print(f"agreement: ssim mean {abs(s_lib - s_new):.1e}, map {np.abs(m_lib - m_new).max():.1e}")
    for mode, (a, b) in (("LDR", (rd, xd)), ("HDR", (ref, x))):
        f_lib, e_lib = M.flip(a, b, mode, "library")
        f_new, e_new = M.flip(a, b, mode)
        print(f"agreement: flip {mode} mean {abs(f_lib - f_new):.1e} (library sums in float32), "
              f"map {np.abs(e_lib - e_new).max():.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
