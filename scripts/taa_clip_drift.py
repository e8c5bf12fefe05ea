"""Drift of the Dr.Jit float32 TAAs from the float64 NumPy oracle over whole sequences.

Each runs on its own history (the oracle never sees the kernels' output), over the ghosting
schedule (frame t at scene time t, jitter halton_offset(t, 16), reset at t = 0 and at cuts).
Prints, per scene and TAA, the largest |float32 - float64| of the displayed output and of the
history as a fraction of the frame's peak input colour, and where it first exceeds 1e-3.

    .venv/bin/python scripts/taa_clip_drift.py [--size 64x36] [--frames 12] [--clip-tol X]
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

import backend  # noqa: E402,F401
import taa_impl  # noqa: E402
from tests.oracle_taa import OracleTAA  # noqa: E402

SCENES = ("fast_object", "camera_cut", "disocclusion", "hdr_contrast")
BUFS = ("color", "albedo", "depth", "object_id", "motion", "prev_depth")


def render_sequence(name: str, w: int, h: int, n: int, cache_dir: Path | None = None):
    """(frames, resets, far) of the ghosting schedule's first n steps, cached as .npz."""
    from raster import Rasterizer
    from scenes import get_scene
    from scenes.jitter import TAA_PERIOD, halton_offset
    scene = get_scene(name)
    far = float(scene.desc.camera.far)
    path = cache_dir / f"{name}_{w}x{h}_{n}.npz" if cache_dir else None
    # study.config.protocols.ghosting_schedule: step t shows time t with jitter k = t, motion from t - 1
    steps = [(t, t, t - 1) for t in range(n)]
    resets = [scene.is_cut(t) for t in range(n)]
    if path is not None and path.exists():
        z = np.load(path)
        frames = [{b: z[f"{i}_{b}"] for b in BUFS} for i in range(n)]
        return frames, resets, far
    r = Rasterizer(scene, w, h)
    try:
        frames = [r.render(t, halton_offset(k, TAA_PERIOD), BUFS, prev_t=pt) for t, k, pt in steps]
    finally:
        r.close()
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **{f"{i}_{b}": fr[b] for i, fr in enumerate(frames) for b in BUFS})
    return frames, resets, far


def drift(name: str, frames, resets, far, **overrides):
    """Per frame: (max output drift / peak, max history drift / peak, argmax (y, x, ch))."""
    from scenes.jitter import TAA_PERIOD, halton_offset
    tech = taa_impl.make(name, **overrides)
    oracle = OracleTAA(tech.params, improved=name == "taa_improved", dtype=np.float64)
    rows = []
    for i, (fr, reset) in enumerate(zip(frames, resets)):
        out = tech.process(fr, jitter=halton_offset(i, TAA_PERIOD), far=far, reset=reset)
        ref = oracle.process(fr, far=far, reset=reset)
        peak = float(np.abs(fr["color"]).max())
        d_out = np.abs(out.astype(np.float64) - ref)
        d_hist = np.abs(tech.history.astype(np.float64) - oracle.history)
        where = np.unravel_index(int(np.argmax(d_out)), d_out.shape)
        rows.append((d_out.max() / peak, d_hist.max() / peak, where,
                     float(out[where]), float(ref[where])))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="64x36")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--clip-tol", type=float, default=None,
                    help="override TAAParams.clip_tol (0 = INSIDE's absolute eps only)")
    ap.add_argument("--cache", default="/tmp/taa_clip_drift")
    a = ap.parse_args(argv)
    w, h = (int(v) for v in a.size.lower().split("x"))
    overrides = {} if a.clip_tol is None else {"clip_tol": a.clip_tol}
    print(f"{a.size}, {a.frames} frames, overrides {overrides or 'none'}")
    print(f"{'scene':14s} {'technique':13s} {'out/peak':>9s} {'hist/peak':>9s}  first > 1e-3 (t, y, x, ch: f32 vs f64)")
    worst = 0.0
    for scene in SCENES:
        frames, resets, far = render_sequence(scene, w, h, a.frames, Path(a.cache))
        for name in ("taa_baseline", "taa_improved"):
            rows = drift(name, frames, resets, far, **overrides)
            d_out = max(r[0] for r in rows)
            d_hist = max(r[1] for r in rows)
            worst = max(worst, d_out)
            first = next(((t, r) for t, r in enumerate(rows) if r[0] > 1e-3), None)
            where = (f"t={first[0]} {tuple(int(v) for v in first[1][2])}: "
                     f"{first[1][3]:.5f} vs {first[1][4]:.5f}") if first else "-"
            print(f"{scene:14s} {name:13s} {d_out:9.2e} {d_hist:9.2e}  {where}")
    print(f"worst output drift / peak: {worst:.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
