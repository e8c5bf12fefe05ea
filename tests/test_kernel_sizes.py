"""Size-agnostic Dr.Jit kernels: a technique run at a second image size (with other far planes,
jitters and cameras) launches only kernels it already launched at the first size. Sizes, scale
factors and per-frame constants reach the kernels as opaque parameters (taa_impl.kernels.Grid,
opaque_float), so a study's several sizes and the test suite's many compile each kernel once.

Kernels are compared by the hash of their code (Dr.Jit's kernel history), not by cache hits:
a disk-cached kernel from an earlier run would count as a hit and hide a size-specific kernel."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)
from backend import dr

import taa_impl
from display import DisplayTransform
from scenes.camera import CameraState, look_at
from study.commands.bench import synthetic_frame

# the main TAAs, their extensions, Ferrando's camera-only TAA, the upscalers and the post-processes
NAMES = ["taa_baseline", "taa_improved", "taa_ycocg_variance", "taa_reject", "taa_sparse",
         "taa_ferrando_text", "taau", "upscale_spatial", "fsr2", "fxaa", "smaa"]
# Dr.Jit's LLVM scatter-reduce (FSR 2's reconstructed previous depth, a float min) writes per-thread
# copies of its target whose size is a literal of that one kernel
ALLOWED_NEW = {"fsr2": 1}


def _camera(k, w, h):
    return CameraState(look_at((0.03 * k, 0.01 * k, 5.0), (0, 0, 0), (0, 1, 0)), 45.0, 0.1, 100.0, w, h)


def _run(tech, w, h, far0):
    """Three frames at an output of w x h; each frame has its own far plane, jitter and cameras."""
    tech.reset()
    rw, rh, size = w, h, {}
    if tech.inputs.upsamples:
        rw, rh = taa_impl.render_size(w, h, tech.params.render_scale)
        size = {"output_size": (w, h)}
    for k in range(3):
        f = synthetic_frame(rw, rh, seed=k)
        kw = dict(size)
        if tech.inputs.display:
            kw["display"] = DisplayTransform.from_reference(f["color"])
        if tech.inputs.cameras:
            kw["cameras"] = (_camera(k + 1, w, h), _camera(k, w, h))
        if tech.inputs.extra_samples:
            kw["supersampled"] = f["color"]
            kw["mask"] = tech.invalid_mask(f, far=far0 + k)
        out = tech.process(f, jitter=(0.1 * k - 0.2, 0.3 - 0.15 * k), far=far0 + 7.5 * k, **kw)
        assert out.shape == (h, w, 3) and np.isfinite(out).all()


def _kernels(fn):
    """Hashes of the JIT kernels `fn` launches."""
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history()                       # clears it
        fn()
        hist = dr.kernel_history()
    return {e["hash"] for e in hist if e["type"] == dr.KernelType.JIT}


@pytest.mark.parametrize("name", NAMES)
def test_a_second_size_compiles_no_new_kernel(name):
    tech = taa_impl.make(name)
    first = _kernels(lambda: _run(tech, 40, 23, 100.0))
    assert first, "no kernel was launched: nothing measured"
    second = _kernels(lambda: _run(tech, 52, 31, 37.0))
    new = second - first
    assert len(new) <= ALLOWED_NEW.get(name, 0), \
        f"{name}: {len(new)} of {len(second)} kernels at 52x31 are new (a size or frame constant as a literal)"


def test_accumulation_compiles_one_mean_for_every_count():
    """The running mean divides by the frame count: as a literal, every count was a new kernel
    (a 128-sample reference compiled 128)."""
    tech = taa_impl.make("accumulation", samples=6)
    frames = [synthetic_frame(20, 12, seed=k) for k in range(6)]
    first = _kernels(lambda: [tech.process(f, far=50.0) for f in frames[:2]])
    later = _kernels(lambda: [tech.process(f, far=50.0) for f in frames[2:]])
    assert first and not (later - first), f"{len(later - first)} new kernels for counts 3-6"
    want = np.mean(np.stack([f["color"].astype(np.float64) for f in frames]), 0).astype(np.float32)
    np.testing.assert_array_equal(tech.mean, want)
