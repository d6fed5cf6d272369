"""Fixtures shared by the test folders."""
import pytest


@pytest.fixture(scope="session")
def mi():
    """Mitsuba with the llvm_ad_spectral variant (LLVM 19 located by select_variant)."""
    from workbench.render.variants import import_mitsuba
    try:
        return import_mitsuba("llvm_ad_spectral")
    except (ImportError, AttributeError, ValueError, RuntimeError) as exc:
        pytest.skip(f"llvm_ad_spectral unavailable: {exc}")
