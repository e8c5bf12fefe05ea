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
