"""`taa-study bench`: per-frame cost of every technique on the current Dr.Jit backend, against
the NumPy oracle on the same input and a memory-bandwidth floor measured in the same run.

- Dr.Jit time: for the plain TAAs, the technique's kernel on inputs already in Dr.Jit arrays,
  forced to finish with dr.sync_thread() (the LLVM backend runs asynchronously), warm (the
  compiling runs excluded), median of repeated runs; for the others (FXAA, SMAA, camera-only and
  sparse TAAs, accumulation) the end-to-end time, which is also given for every technique
  (process(): NumPy in, NumPy out).
- NumPy: the oracle in tests/oracle_taa.py (plain NumPy, written for clarity) on the same frame.
- Bandwidth floor: bytes the technique must read and write per pixel (its buffers, the history it
  reads and writes, its output) divided by the copy bandwidth of this machine, measured with a
  Dr.Jit copy kernel over 256 MiB.
- Upscalers (taa_impl.upscale) are timed at each render scale (`render_scales`, the full study's
  by default), one entry each ('fsr2 ×0.5'): a frame at render_size(width, height, scale) in,
  the width x height output out; their floor counts the inputs at that scale.
"""
from __future__ import annotations

import importlib.util
import statistics
import time
from pathlib import Path

import numpy as np

import backend
from backend import dr, mi

from study.engine.costs import median_ms

BYTES = {"color": 12, "albedo": 12, "depth": 4, "object_id": 4, "prim_id": 4, "normal": 12, "motion": 8,
         "prev_depth": 4, "light_mask": 4}


def synthetic_frame(width: int, height: int, seed: int = 0) -> dict[str, np.ndarray]:
    """A plausible frame: smooth colour with edges, blocks of objects, small motion."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    obj = ((x // 97 + y // 61) % 5 + 1).astype(np.int32)
    colour = np.stack([0.5 + 0.4 * np.sin(x / 37 + obj), 0.5 + 0.4 * np.cos(y / 23), (obj % 3) / 3.0], -1)
    colour = (colour + 0.02 * rng.standard_normal(colour.shape)).clip(0).astype(np.float32)
    depth = (5 + obj + 0.001 * x).astype(np.float32)
    motion = (rng.uniform(-2, 2, (height, width, 2))).astype(np.float32)
    return {"color": colour, "albedo": (colour * 0.8).astype(np.float32), "depth": depth, "object_id": obj,
            "motion": motion, "prev_depth": (depth + 0.01).astype(np.float32)}


def copy_bandwidth(repeats: int = 7) -> float:
    """Bytes per second of a read-plus-write copy kernel (256 MiB each way)."""
    n = 64 * 1024 * 1024
    src = dr.arange(mi.Float, n)
    one = dr.opaque(mi.Float, 1.0)    # opaque, so the JIT cannot fold the copy away
    dr.eval(src)
    times = []
    for _ in range(repeats + 2):
        dr.sync_thread()
        t0 = time.perf_counter()
        dst = src * one
        dr.eval(dst)
        dr.sync_thread()
        times.append(time.perf_counter() - t0)
        del dst
    return 2 * 4 * n / statistics.median(times[2:])


def _oracle_module():
    path = Path(__file__).resolve().parents[2] / "tests" / "oracle_taa.py"     # the checkout's tests/
    if not path.exists():
        return None
    spec = importlib.util.spec_from_file_location("oracle_taa", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# the full study's render scales (study/config/profiles/full.toml)
RENDER_SCALES = (0.5, 0.67, 0.77, 1.0)


def bytes_per_pixel(tech) -> float:
    """Bytes read and written per output pixel: the inputs (at an upscaler's render scale), the
    history, the output."""
    state = int(getattr(tech, "history_bytes_per_pixel", 0))
    inp = tech.inputs
    inputs = inp.subframes * sum(BYTES.get(b, 4) for b in inp.buffers) * inp.render_scale ** 2
    return inputs + state + 12   # + the output


def _extra_inputs(tech, frame, width, height) -> dict:
    """What the driver would pass besides the frame: display transform, cameras, extra samples."""
    from display import DisplayTransform
    from scenes.camera import CameraState, look_at
    kw = {}
    inp = tech.inputs
    if inp.display:
        kw["display"] = DisplayTransform.from_reference(frame["color"])
    if inp.cameras:
        cam = CameraState(look_at((0, 0, 5), (0, 0, 0), (0, 1, 0)), 45.0, 0.1, 100.0, width, height)
        prev = CameraState(look_at((0.02, 0, 5), (0, 0, 0), (0, 1, 0)), 45.0, 0.1, 100.0, width, height)
        kw["cameras"] = (cam, prev)
    if inp.extra_samples:   # the extra samples' shading is raster work, not timed here
        kw["supersampled"] = frame["color"]
        kw["mask"] = tech.invalid_mask(frame, far=100.0)
    return kw


def _kernel_only(tech, frame, width, height):
    """The Dr.Jit part alone on inputs already on the device, for plain TAAs; None otherwise."""
    from taa_impl.base import Frame, to_drjit
    inp = tech.inputs
    plain = not (inp.cameras or inp.extra_samples or inp.display)
    if not plain or not hasattr(tech, "_step") or inp.sampling != "sequence":
        return None
    bufs = to_drjit({k: frame[k] for k in tech.needs})
    dr.eval(bufs)
    fr = Frame(buffers=frame, far=100.0, output_size=(width, height))

    def kernel():
        r = tech._step(bufs, fr)
        dr.eval(r)
        dr.sync_thread()
    return kernel


def _runs(names, render_scales):
    """(entry label, technique) for each name; an upscaler once per render scale."""
    import taa_impl
    for name in names:
        tech = taa_impl.make(name)
        if getattr(tech, "upsamples", False):
            for s in render_scales:
                yield f"{name} ×{float(s):g}", taa_impl.make(name, render_scale=float(s))
        else:
            yield name, tech


def bench(width: int, height: int, repeats: int = 7, techniques=None, numpy_repeats: int = 3,
          log=print, render_scales=RENDER_SCALES) -> dict:
    """Per-frame milliseconds of each technique (upscalers at each of `render_scales`) at an output
    of width x height; see the module notes for what is timed."""
    import taa_impl
    from taa_impl.upscale import render_size
    frame = synthetic_frame(width, height)
    bw = copy_bandwidth()
    log(f"copy bandwidth: {bw / 1e9:.2f} GB/s")
    oracle = _oracle_module()
    names = techniques or [n for n in taa_impl.TECHNIQUES]
    out = {"width": width, "height": height, "backend": backend.VARIANT, "copy_bandwidth_gbs": bw / 1e9,
           "render_scales": [float(s) for s in render_scales],
           "techniques": {}, "end_to_end_ms": {}, "numpy_ms": {}, "bandwidth_floor_ms": {}}
    for name, tech in _runs(names, render_scales):
        log(f"timing {name} ...")
        size = {}
        src = frame
        if getattr(tech, "upsamples", False):
            rw, rh = render_size(width, height, tech.params.render_scale)
            src = synthetic_frame(rw, rh)
            size = {"output_size": (width, height)}
        kw = {**_extra_inputs(tech, src, width, height), **size}
        if tech.inputs.sampling == "supersample":
            subs = [frame] * tech.inputs.subframes
            out["end_to_end_ms"][name] = median_ms(lambda: tech.process(samples=subs, far=100.0), repeats)
            out["techniques"][name] = {"ms": out["end_to_end_ms"][name]}
        else:
            run = lambda: tech.process(src, jitter=(0, 0), far=100.0, **kw)  # noqa: E731
            run()                                        # compile, fill history
            out["end_to_end_ms"][name] = median_ms(run, repeats)
            kernel = None if size else _kernel_only(tech, frame, width, height)
            out["techniques"][name] = {"ms": median_ms(kernel, repeats) if kernel else out["end_to_end_ms"][name]}
        out["bandwidth_floor_ms"][name] = 1000 * bytes_per_pixel(tech) * width * height / bw
        if oracle is not None and name in ("taa_baseline", "taa_improved"):
            o = oracle.OracleTAA(tech.params, improved=(name == "taa_improved"))
            o.process(frame, 100.0)
            out["numpy_ms"][name] = median_ms(lambda: o.process(frame, 100.0), numpy_repeats, warmup=0)
    return out
