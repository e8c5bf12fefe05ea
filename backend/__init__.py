"""Selects the Dr.Jit/Mitsuba backend before either is imported.

Dr.Jit's LLVM backend loads libLLVM at run time. Debian's LLVM 15 makes it abort the whole process
("Cannot select ... fmaximum") and LLVM 14 is refused, so we pick a recent library ourselves and
fail with an instruction instead of an abort. Import `dr` and `mi` from here, never directly.
"""
from __future__ import annotations

import glob
import os
import re
import sys

MIN_LLVM = 16  # 15 aborts (measured); 19 is what Debian 12 backports ship and is tested.

_SEARCH = (
    "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
)


class BackendError(RuntimeError):
    pass


def _llvm_major(path: str) -> int | None:
    m = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path)) or re.search(r"llvm-(\d+)", path)
    return int(m.group(1)) if m else None


def find_libllvm() -> str:
    """Path of the newest libLLVM >= MIN_LLVM on this machine, or BackendError saying what to install."""
    found = []
    for pattern in _SEARCH:
        for path in glob.glob(pattern):
            major = _llvm_major(path)
            if major is not None and os.path.isfile(path):
                found.append((major, path))
    good = sorted((m, p) for m, p in found if m >= MIN_LLVM)
    if not good:
        seen = ", ".join(sorted({p for _, p in found})) or "none"
        raise BackendError(
            f"Dr.Jit's LLVM backend needs libLLVM >= {MIN_LLVM} (LLVM 15 aborts the process, 14 is "
            f"refused); found: {seen}. Install one with `apt-get install libllvm19` "
            "or set DRJIT_LIBLLVM_PATH to a suitable libLLVM.so.")
    return good[-1][1]


# The Mitsuba variants this project runs: RGB (shading and references use Color3f) with Dr.Jit's
# JIT arrays (every technique is a Dr.Jit kernel; scalar_rgb has none).
SUPPORTED_VARIANTS = {"llvm_ad_rgb": "the CPU, the default", "cuda_ad_rgb": "an NVIDIA GPU"}


def requested_variant() -> str:
    return os.environ.get("TAA_VARIANT", "").strip() or "llvm_ad_rgb"


def check_variant(variant: str) -> str:
    """`variant` if this project runs on it, else BackendError naming TAA_VARIANT and the choices."""
    if variant not in SUPPORTED_VARIANTS:
        choices = ", ".join(f"{k} ({v})" for k, v in SUPPORTED_VARIANTS.items())
        raise BackendError(f"TAA_VARIANT={variant!r} is not a variant this project runs; use one of: {choices}")
    return variant


def _configure() -> None:
    variant = check_variant(requested_variant())
    if not variant.startswith("llvm"):
        return
    path = os.environ.get("DRJIT_LIBLLVM_PATH")
    if path:
        major = _llvm_major(path)
        if not os.path.isfile(path):
            raise BackendError(f"DRJIT_LIBLLVM_PATH={path!r} does not exist")
        if major is not None and major < MIN_LLVM:
            raise BackendError(f"DRJIT_LIBLLVM_PATH={path!r} is LLVM {major}; "
                               f"Dr.Jit needs >= {MIN_LLVM} (apt-get install libllvm19)")
        return
    if "drjit" in sys.modules:
        raise BackendError("drjit was imported before backend could select libLLVM; "
                           "import backend first or set DRJIT_LIBLLVM_PATH")
    os.environ["DRJIT_LIBLLVM_PATH"] = find_libllvm()


_configure()

import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

VARIANT = requested_variant()
if VARIANT.startswith("cuda") and not dr.has_backend(dr.JitBackend.CUDA):
    raise BackendError(f"TAA_VARIANT={VARIANT!r}: no CUDA device was found (Dr.Jit's CUDA backend did not "
                       "start); unset TAA_VARIANT to run on the CPU (llvm_ad_rgb)")
try:
    mi.set_variant(VARIANT)
except Exception as exc:  # an unknown or unavailable variant (cuda without a GPU)
    raise BackendError(f"Mitsuba variant {VARIANT!r} is not available here: {exc}") from exc



def opaque(cls, *values):
    """A Dr.Jit value of type `cls` (mi.Float, mi.Vector3f, mi.Color3f, ...) from Python numbers,
    held in memory rather than compiled into the kernel as a literal: a per-frame camera, jitter
    or light as a literal makes every frame's kernel new, to be compiled again (and again on every
    new machine); opaque, one kernel serves every frame and scene of the same structure."""
    comps = [dr.opaque(mi.Float, float(v)) for v in values]
    return comps[0] if cls is mi.Float else cls(*comps)


ALIGN = 64


def aligned(a, dtype=None):
    """`a` as a C-contiguous numpy array whose memory starts on a 64-byte boundary (a copy only
    when it does not). Dr.Jit maps a contiguous numpy array's memory instead of copying it, and
    the kernel that reads it states that memory's alignment (`align 64` or `align 1`): from
    numpy's allocator, 16-byte aligned, the same frame's kernel came out one way or the other by
    chance, and was compiled again (a flaky kernel-reuse test, 2 runs in 40). Only arrays loaded at
    each lane's own index are affected; a gather's source states no alignment."""
    import numpy as np
    a = np.asarray(a, dtype)
    if a.flags.c_contiguous and a.ctypes.data % ALIGN == 0:
        return a
    buf = np.empty(a.nbytes + ALIGN, np.uint8)
    off = -buf.ctypes.data % ALIGN
    out = buf[off:off + a.nbytes].view(a.dtype).reshape(a.shape)
    out[...] = a
    return out


def array(cls, a, dtype=None):
    """A flat Dr.Jit array of type `cls` from numpy data `a`, read from 64-byte aligned memory so
    that its kernels do not depend on where numpy happened to allocate it (see `aligned`)."""
    return cls(aligned(a, dtype).reshape(-1))


__all__ = ["dr", "mi", "VARIANT", "SUPPORTED_VARIANTS", "BackendError", "check_variant", "find_libllvm", "opaque", "aligned", "array"]
