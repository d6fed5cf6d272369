"""Variant selection: preference, fallback order and clear refusals (pure choice + this machine)."""
import os

import pytest

from workbench.render.variants import SPECTRAL_VARIANTS, choose_variant, find_libllvm, select_variant

ALL = list(SPECTRAL_VARIANTS)


def test_prefers_gpu_then_cpu_jit_then_scalar():
    assert choose_variant(ALL, {"cuda": True, "llvm": True})[0] == "cuda_ad_spectral"
    v, why = choose_variant(ALL, {"cuda": False, "llvm": True})
    assert v == "llvm_ad_spectral" and "cuda backend is not available" in why[0]
    v, why = choose_variant(ALL, {"cuda": False, "llvm": False})
    assert v == "scalar_spectral" and len(why) == 2


def test_preference_and_missing_builds():
    assert choose_variant(ALL, {"cuda": True, "llvm": True}, "scalar_spectral")[0] == "scalar_spectral"
    v, why = choose_variant(["scalar_spectral"], {"cuda": True, "llvm": True}, "llvm_ad_spectral")
    assert v == "scalar_spectral" and "not compiled" in why[0]


def test_refusals_name_the_value():
    with pytest.raises(ValueError, match="llvm_ad_rgb"):
        choose_variant(ALL, {}, "llvm_ad_rgb")
    with pytest.raises(ValueError, match="no spectral Mitsuba variant"):
        choose_variant(["scalar_rgb"], {"cuda": True, "llvm": True})


def test_this_machine_sets_llvm_path_and_a_spectral_variant():
    v = select_variant()
    assert v in SPECTRAL_VARIANTS
    import mitsuba as mi
    assert mi.variant() == v
    if find_libllvm() is not None:
        assert os.environ.get("DRJIT_LIBLLVM_PATH")
    assert select_variant("scalar_spectral") == "scalar_spectral"
    select_variant()


def llvm_fails_to_load(monkeypatch) -> None:
    """Make mitsuba.set_variant('llvm_ad_spectral') raise, as a JIT that cannot start does."""
    import mitsuba as mi

    select_variant("scalar_spectral")
    real = mi.set_variant

    def failing(name, *args):
        if name == "llvm_ad_spectral":
            raise RuntimeError("simulated JIT start-up failure")
        return real(name, *args)

    monkeypatch.setattr(mi, "set_variant", failing)


def test_a_variant_that_fails_to_load_falls_back(monkeypatch, caplog):
    llvm_fails_to_load(monkeypatch)
    with caplog.at_level("WARNING"):
        assert select_variant("llvm_ad_spectral") == "scalar_spectral"
    assert "simulated JIT start-up failure" in caplog.text
    monkeypatch.undo()
    assert select_variant() == "llvm_ad_spectral" or not find_libllvm()


def test_an_nvidia_gpu_gets_the_cuda_variant_automatically(monkeypatch, caplog):
    """Simulated GPU machine: Dr.Jit reports a CUDA backend, so select_variant() asks for
    cuda_ad_spectral with no preference given; if its start fails, it falls back to the CPU JIT."""
    import drjit as dr
    import mitsuba as mi

    select_variant()
    real_set, asked = mi.set_variant, []

    def fake_set(name, *args):
        asked.append(name)
        if name != "cuda_ad_spectral":
            return real_set(name, *args)
    monkeypatch.setattr(dr, "has_backend", lambda backend: True)
    monkeypatch.setattr(mi, "variants", lambda: list(SPECTRAL_VARIANTS) + ["scalar_rgb"])
    monkeypatch.setattr(mi, "set_variant", fake_set)
    assert select_variant() == "cuda_ad_spectral" and asked == ["cuda_ad_spectral"]

    def no_driver(name, *args):
        if name == "cuda_ad_spectral":
            raise RuntimeError("simulated: cuInit failed, no CUDA driver")
        return real_set(name, *args)
    monkeypatch.setattr(mi, "set_variant", no_driver)
    with caplog.at_level("WARNING"):
        assert select_variant() in ("llvm_ad_spectral", "scalar_spectral")
    assert "cuda_ad_spectral failed to load" in caplog.text and "cuInit" in caplog.text


def test_a_pinned_variant_is_that_variant_or_a_refusal_naming_the_field(monkeypatch):
    from workbench.errors import ParameterError
    with pytest.raises(ParameterError, match="render.variant.*cuda backend is not available"):
        choose_variant(ALL, {"cuda": False, "llvm": True}, "cuda_ad_spectral", strict=True)
    with pytest.raises(ParameterError, match="not compiled"):
        choose_variant(["scalar_spectral"], {"llvm": True}, "llvm_ad_spectral", strict=True)
    assert choose_variant(ALL, {"cuda": False, "llvm": True}, "llvm_ad_spectral", strict=True)[0] == "llvm_ad_spectral"
    llvm_fails_to_load(monkeypatch)
    with pytest.raises(ParameterError, match="failed to load"):
        select_variant("llvm_ad_spectral", strict=True)
    monkeypatch.undo()
    select_variant()
