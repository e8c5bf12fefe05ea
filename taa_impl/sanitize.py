"""Input validation and repair of non-finite pixels, before anything reaches the history.

A NaN or Inf that entered the history would stay there for ever (every later blend mixes it in) and
would spread through the bilinear fetch and the neighbourhood box. So every non-finite input pixel
is replaced before use, and counted so the study can report it:
- colour-like buffers (color, albedo) and depth: the mean of the finite pixels of the 3x3
  neighbourhood (clamp-to-edge, like every gather here); if none is finite: 0 for colours,
  `far` (background) for depth;
- prev_depth: the (repaired) current depth of the pixel;
- motion: (0, 0) (reuse the pixel's own history; the clip box still guards it).
This runs in NumPy on the input arrays (it is a no-op copy when everything is finite).
"""
from __future__ import annotations

import weakref

import numpy as np

_SHAPES = {"color": 3, "albedo": 3, "motion": 2, "depth": 0, "prev_depth": 0, "object_id": 0}
_NEIGHBOURS = [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dx, dy) != (0, 0)]


def fill_from_neighbours(img: np.ndarray, bad: np.ndarray, fallback: float) -> np.ndarray:
    """Replace pixels where `bad` by the mean of their finite (not bad) 3x3 neighbours."""
    h, w = bad.shape
    good = ~bad
    vals = np.where(good.reshape(h, w, *([1] * (img.ndim - 2))), img, 0).astype(np.float32)
    ys, xs = np.arange(h)[:, None], np.arange(w)[None, :]
    acc = np.zeros_like(vals)
    cnt = np.zeros((h, w), np.float32)
    for dx, dy in _NEIGHBOURS:
        yy = np.clip(ys + dy, 0, h - 1)
        xx = np.clip(xs + dx, 0, w - 1)
        g = good[yy, xx]
        acc += vals[yy, xx] * g.reshape(h, w, *([1] * (img.ndim - 2)))
        cnt += g
    c = cnt.reshape(h, w, *([1] * (img.ndim - 2)))
    repl = np.where(c > 0, acc / np.maximum(c, 1), np.float32(fallback)).astype(np.float32)
    return np.where(bad.reshape(c.shape), repl, img).astype(np.float32)


# Read-only buffers already found finite, by id (weakly: a freed array's entry goes with it). The
# study's frame source hands every technique of a step the same read-only buffers, so the check
# is made once per frame, not once per technique; a writeable buffer is checked on every call.
_FINITE: dict[int, weakref.ref] = {}


def read_only(a) -> bool:
    """Whether no array in `a`'s chain of bases can be written (a read-only view of a writeable
    array can change under it)."""
    while isinstance(a, np.ndarray):
        if a.flags.writeable:
            return False
        a = a.base
    return True


def freeze(a: np.ndarray) -> np.ndarray:
    """`a`, made read-only down its chain of bases (what `read_only` asks), for buffers several
    techniques read: none can change another's input, and one check of finiteness holds for all."""
    x = a
    while isinstance(x, np.ndarray):
        x.flags.writeable = False
        x = x.base
    return a


def _known_finite(a: np.ndarray) -> bool:
    r = _FINITE.get(id(a))
    return r is not None and r() is a and read_only(a)


def _remember_finite(a: np.ndarray) -> None:
    if not read_only(a):
        return
    k = id(a)
    _FINITE[k] = weakref.ref(a, lambda _r, k=k: _FINITE.pop(k, None))


def _bad_pixels(a: np.ndarray) -> np.ndarray:
    fin = np.isfinite(a)
    return ~(fin.all(axis=-1) if a.ndim == 3 else fin)


def check_and_repair(frame: dict, needs, shape: tuple[int, int], far: float) -> dict:
    """The needed buffers as contiguous float32/int32 arrays of the right shape, non-finite pixels
    repaired; `out['_nonfinite']` maps buffer name -> number of repaired pixels."""
    h, w = shape
    out, counts = {}, {}
    for key in sorted(needs):
        if key not in _SHAPES:
            raise KeyError(f"unknown buffer {key!r}")
        a = np.asarray(frame[key])
        want = (h, w, _SHAPES[key]) if _SHAPES[key] else (h, w)
        if a.shape != want:
            raise ValueError(f"buffer {key!r} has shape {a.shape}, expected {want}")
        if key == "object_id":
            out[key] = np.ascontiguousarray(a, dtype=np.int32)
            continue
        out[key] = np.ascontiguousarray(a, dtype=np.float32)
    for key in ("color", "albedo", "depth", "motion", "prev_depth"):  # depth before prev_depth
        if key not in out:
            continue
        a = out[key]
        if _known_finite(a):
            counts[key] = 0
            continue
        # Fast path: NaN and +-Inf make the float64 sum non-finite, so a finite sum proves a clean
        # buffer in one pass (an overflowing sum only sends us to the exact check).
        if np.isfinite(np.sum(a, dtype=np.float64)):
            counts[key] = 0
            _remember_finite(a)
            continue
        bad = _bad_pixels(a)
        counts[key] = n = int(bad.sum())
        if n == 0:
            continue
        if key == "motion":
            out[key] = np.where(bad[..., None], np.float32(0), a)
        elif key == "prev_depth":
            cur = out.get("depth")
            out[key] = np.where(bad, cur if cur is not None else np.float32(far), a).astype(np.float32)
        else:
            out[key] = fill_from_neighbours(a, bad, far if key == "depth" else 0.0)
    out["_nonfinite"] = counts
    return out
