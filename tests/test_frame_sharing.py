"""The raster frames a run shares between its techniques: read-only and aligned once, and checked
for NaN/Inf once per frame (taa_impl.sanitize), never at the cost of a NaN getting through."""
import numpy as np
import pytest

from backend import ALIGN
from taa_impl import sanitize as S
from study.engine.drive import _shared


def _frame(h=4, w=5):
    rng = np.random.default_rng(1)
    return {"color": rng.random((h, w, 3), np.float32), "depth": rng.random((h, w), np.float32) + 1}


def test_a_shared_buffer_is_aligned_read_only_and_equal():
    f = _frame()
    for k, a in f.items():
        s = _shared(a)
        assert np.array_equal(s, a) and s.dtype == a.dtype
        assert s.ctypes.data % ALIGN == 0
        assert S.read_only(s)
        with pytest.raises(ValueError):      # one technique cannot change the next one's input
            s[0, 0] = 0


def test_a_read_only_frame_is_checked_once_and_a_writeable_one_every_time(monkeypatch):
    shared = {k: _shared(a) for k, a in _frame().items()}
    sums = []
    real = np.sum
    monkeypatch.setattr(S.np, "sum", lambda a, *x, **kw: (sums.append(a.shape), real(a, *x, **kw))[1])
    for _ in range(3):
        S.check_and_repair(shared, ("color", "depth"), (4, 5), far=10.0)
    assert len(sums) == 2                    # color and depth, on the first call only
    plain = _frame()
    sums.clear()
    for _ in range(3):
        S.check_and_repair(plain, ("color", "depth"), (4, 5), far=10.0)
    assert len(sums) == 6


def test_a_nan_written_through_a_writeable_base_is_still_found():
    base = _frame()["color"]
    view = base.view()
    view.flags.writeable = False             # read-only itself, but its base is not
    out = S.check_and_repair({"color": view}, ("color",), (4, 5), far=10.0)
    assert out["_nonfinite"]["color"] == 0
    base[1, 2, 0] = np.nan
    out = S.check_and_repair({"color": view}, ("color",), (4, 5), far=10.0)
    assert out["_nonfinite"]["color"] == 1 and np.all(np.isfinite(out["color"]))


def test_a_writeable_buffer_made_nan_after_a_clean_check_is_found():
    f = _frame()
    S.check_and_repair(f, ("color",), (4, 5), far=10.0)
    f["color"][0, 0, 1] = np.inf
    out = S.check_and_repair(f, ("color",), (4, 5), far=10.0)
    assert out["_nonfinite"]["color"] == 1
