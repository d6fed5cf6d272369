"""Missing back-ends are named with what to install (first-run messages)."""
from workbench import diagnostics
from workbench.render import variants


def test_missing_llvm_says_what_to_install(monkeypatch):
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.setattr(variants, "find_libllvm", lambda: None)
    llvm = next(c for c in diagnostics.check_environment() if c.name.startswith("LLVM"))
    assert not llvm.ok and "libllvm19" in llvm.detail and "DRJIT_LIBLLVM_PATH" in llvm.detail


def test_found_llvm_reports_its_path(monkeypatch, tmp_path):
    lib = tmp_path / "libLLVM.so.19.1"
    lib.write_bytes(b"")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(lib))
    llvm = next(c for c in diagnostics.check_environment() if c.name.startswith("LLVM"))
    assert llvm.ok and llvm.detail == str(lib)


def test_no_display_says_what_to_install(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    gl = next(c for c in diagnostics.check_environment() if c.name.startswith("OpenGL"))
    assert not gl.ok and "xvfb" in gl.detail
