"""Reference cost and per-pixel noise: pipe, atrium, hairball_rotating_lit at 320x180 and pipe at
1600x900, or with --textured the three textured example scenes of
scenes/examples/textured/ at 320x180, rendered into a temporary cache.

Prints seconds, mean/max spp, the 99.9th percentile and max display-domain standard error in LSB
(8-bit), the count of pixels over the bound and of those whose SE is the unseen-feature floor. A reference that records no display-domain error
(older code) gets it from its linear error by the delta method, marked "(delta)". "needed": the
samples the worst pixel still over the bound would take, predicted by the renderer ("-": older code).

    .venv/bin/python scripts/bench_reference.py [--skip-full] [--textured] [--only SCENE@WxH ...]
        [--bound LSB --held-out --frames N [--reuse]]

`--bound 8 --held-out --frames 2`: frames 0 and 1 at the figures' rule's probe, as a study renders a
ghosting test's references (`--reuse`: frame 1 keeps frame 0's unchanged pixels); a row a frame.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

import backend  # noqa: E402,F401
from display import DisplayTransform  # noqa: E402
from references import ReferenceCache  # noqa: E402
from scenes import get_scene  # noqa: E402

CASES = [("pipe", 320, 180), ("atrium", 320, 180), ("hairball_rotating_lit", 320, 180), ("pipe", 1600, 900)]
_EXAMPLES = Path(__file__).resolve().parent.parent / "scenes" / "examples" / "textured"
TEXTURED = [(str(_EXAMPLES / f"{n}.toml"), 320, 180) for n in ("checker_grazing", "thin_lines", "leaf")]
BOUND_LSB = 0.5


def delta_display_se(img: np.ndarray, se: np.ndarray) -> np.ndarray:
    """Display-domain SE per channel from linear SE, linearising the display transform per channel."""
    disp = DisplayTransform.from_reference(img)
    base = disp.encode(img)
    var = np.zeros_like(base)
    for k in range(3):
        h = np.maximum(se[..., k].astype(np.float64) * 1e-3, 1e-9)
        x = img.astype(np.float64).copy()
        x[..., k] += h
        slope = (disp.encode(x) - base) / h[..., None]
        var += (slope * se[..., k:k + 1]) ** 2
    return np.sqrt(var)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--skip-full", action="store_true", help="skip pipe at 1600x900")
    ap.add_argument("--textured", action="store_true", help="the textured example scenes")
    ap.add_argument("--only", nargs="*", help="cases as SCENE@WxH")
    ap.add_argument("--bound", type=float, default=None, help="per-pixel bound in LSB (default: the cache's)")
    ap.add_argument("--held-out", action="store_true", help="held-out estimates (the figures' rule)")
    ap.add_argument("--frames", type=int, default=1, help="frames 0..N-1 of each case")
    ap.add_argument("--reuse", action="store_true", help="each frame keeps the previous frame's unchanged pixels")
    args = ap.parse_args()
    kw = {"held_out": args.held_out, "reuse": args.reuse}
    if args.bound is not None:
        kw.update(se_bound_lsb=args.bound, target_noise_db=0.0)
    cases = TEXTURED if args.textured else CASES
    if args.only:
        cases = [(c.split("@")[0], *map(int, c.split("@")[1].split("x"))) for c in args.only]
    elif args.skip_full:
        cases = [c for c in CASES if c[1] < 1600]
    print(f"{'case':32s} {'wall s':>7s} {'ref s':>7s} {'mean spp':>9s} {'max spp':>8s} "
          f"{'p99.9 LSB':>9s} {'max LSB':>8s} {'over':>7s} {'floor':>7s} {'noise dB':>8s} {'needed':>9s}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        cache = ReferenceCache(tmp)
        for name, w, h, t in ((*c, t) for c in cases for t in range(args.frames)):
            scene = get_scene(name)
            name = Path(name).stem + (f" frame {t}" if args.frames > 1 else "")
            t0 = time.perf_counter()
            ref, _ = cache.get(scene, t, w, h, **kw)
            wall = time.perf_counter() - t0
            spp_map = getattr(ref, "spp_map", None)
            spp = np.full((h, w), ref.spp) if spp_map is None else spp_map
            dse = getattr(ref, "display_stderr", None)
            tag = ""
            if dse is None:
                dse, tag = delta_display_se(ref.image, ref.stderr), " (delta)"
            lsb = dse.max(axis=-1) * 255.0
            over = int(np.sum(lsb > (args.bound or BOUND_LSB) * (1 + 1e-5)))    # float32 storage slack
            floor = getattr(ref, "floor_bound", 0)
            print(f"{name + f' {w}x{h}':32s} {wall:7.2f} {ref.seconds:7.2f} {spp.mean():9.1f} {int(spp.max()):8d} "
                  f"{np.percentile(lsb, 99.9):9.3f} {lsb.max():8.3f} {over:7d} {floor:7d} {ref.noise_psnr_db:8.2f} "
                  f"{getattr(ref, 'spp_needed', '-'):>9}{tag}",
                  flush=True)


if __name__ == "__main__":
    main()
