"""The lens library: shipped lenses, then the user's own (saved by the lens editor), by name."""
from __future__ import annotations

import pytest

from workbench.errors import InputFileError
from workbench.optics.lens import available_lenses, load_lens, save_lens
from workbench.optics.lens.io import library_lens_path, user_lens_dir
from workbench.optics.lens.paraxial import paraxial
from workbench.optics.params import OpticsParams


@pytest.fixture
def user_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_LENS_DIR", str(tmp_path / "lenses"))
    return tmp_path / "lenses"


def test_user_lens_is_found_by_name_after_the_shipped_ones(user_dir):
    assert user_lens_dir() == user_dir
    lens = load_lens("dgauss.50mm").scaled(0.5)
    save_lens(lens, user_dir / "half-gauss.json")
    save_lens(load_lens("wide.22mm"), user_dir / "dgauss.50mm.json")       # cannot shadow a shipped lens
    names = available_lenses()
    assert names.index("dgauss.50mm") < names.index("half-gauss") and names.count("dgauss.50mm") == 1
    assert library_lens_path("dgauss.50mm").parent.name == "lenses" and "resources" in str(library_lens_path("dgauss.50mm"))
    assert paraxial(load_lens("half-gauss")).efl_mm == pytest.approx(paraxial(lens).efl_mm)
    assert OpticsParams(lens_file="half-gauss.json", model="psf_grid").lens_file == "half-gauss.json"


def test_missing_user_lens_is_refused_by_name(user_dir):
    with pytest.raises(InputFileError, match="not a library lens"):
        library_lens_path("nope.json")
    with pytest.raises(ValueError, match="nope.json"):
        OpticsParams(lens_file="nope.json")
