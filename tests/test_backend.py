import pytest

import backend


def test_llvm_version_parsing():
    assert backend._llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-19.so") == 19
    assert backend._llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1") == 19
    assert backend._llvm_major("/usr/lib/llvm-17/lib/libLLVM.so") == 17


def test_old_llvm_only_gives_an_instruction(tmp_path, monkeypatch):
    (tmp_path / "libLLVM-15.so").write_bytes(b"")
    (tmp_path / "libLLVM-14.so").write_bytes(b"")
    monkeypatch.setattr(backend, "_SEARCH", (str(tmp_path / "libLLVM*.so*"),))
    with pytest.raises(backend.BackendError, match="apt-get install libllvm19"):
        backend.find_libllvm()
    (tmp_path / "libLLVM-19.so").write_bytes(b"")
    assert backend.find_libllvm().endswith("libLLVM-19.so")


def test_selected_backend_runs():
    from backend import dr, mi
    assert backend.VARIANT.startswith(("llvm", "cuda"))
    assert dr.sum(dr.arange(mi.Float, 5)) == 10


def _kernel_hashes(make, arrays):
    """The hash of the kernel that adds 1 to each array made by `make`."""
    from backend import dr, mi
    hashes = []
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        for a in arrays:
            dr.kernel_history_clear()
            y = make(mi.UInt32, a) + 1
            dr.eval(y)
            assert y.numpy().tolist() == (a + 1).tolist()
            hashes.append({k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT})
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    return hashes


def test_arrays_from_numpy_give_one_kernel_whatever_numpy_memory_alignment():
    """Dr.Jit maps contiguous numpy memory and compiles its alignment into the kernel: the same
    computation on a 64-byte aligned and a 4-byte aligned array is two kernels. backend.array
    reads from aligned memory, so it is one."""
    import numpy as np
    buf = np.arange(4096 + 64, dtype=np.uint32)
    start = (-buf.ctypes.data // 4) % 16           # element index of a 64-byte boundary
    arrays = [buf[start + off:start + off + 4096] for off in (0, 1, 2, 16)]
    assert [a.ctypes.data % 64 for a in arrays] == [0, 4, 8, 0]
    direct = _kernel_hashes(lambda cls, a: cls(a), arrays)
    assert direct[0] == direct[3] and direct[0] != direct[1]      # what the helper protects from
    via_helper = _kernel_hashes(backend.array, arrays)
    assert all(h == via_helper[0] for h in via_helper), via_helper
    for a in arrays:
        al = backend.aligned(a)
        assert al.ctypes.data % 64 == 0 and al.tolist() == a.tolist()
    assert backend.aligned(arrays[0]) is arrays[0]                # no copy when already aligned
    grid = backend.aligned(np.arange(12, dtype=np.float64).reshape(3, 4)[:, ::2], np.float32)
    assert grid.dtype == np.float32 and grid.flags.c_contiguous and grid.tolist() == [[0, 2], [4, 6], [8, 10]]
