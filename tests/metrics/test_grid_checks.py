"""Design-study grids vary what the optics level reads: a field no design's level reads is refused,
one read in part is noted, and the default grid follows the level."""
import pytest

from workbench.errors import ParameterError
from workbench.metrics.grid_checks import BLURRING_GRID, PINHOLE_GRID, check_grid, default_grid
from workbench.metrics.study import parse_vary
from workbench.project import load_project

PINHOLE = load_project("paper_camera")


def test_the_pinhole_default_grid_varies_what_the_pinhole_reads_and_is_not_flagged():
    assert PINHOLE.optics.model == "pinhole" and default_grid(PINHOLE) == PINHOLE_GRID
    assert check_grid(PINHOLE, parse_vary(PINHOLE_GRID.splitlines())) == []
    blurring = PINHOLE.updated(optics=PINHOLE.optics.updated(model="diffraction_limited"))
    assert default_grid(blurring) == BLURRING_GRID
    assert check_grid(blurring, parse_vary(BLURRING_GRID.splitlines())) == []


def test_the_f_number_of_a_pinhole_is_noted_as_irradiance_only():
    notes = check_grid(PINHOLE, parse_vary(BLURRING_GRID.splitlines()))
    assert len(notes) == 1 and notes[0].startswith("optics.f_number: the pinhole level has no blur")
    both = parse_vary(["optics.model=pinhole,diffraction_limited", "optics.f_number=2,8"])
    assert len(check_grid(PINHOLE, both)) == 1                       # the pinhole designs still ignore the blur


@pytest.mark.parametrize("field", ["optics.psf_field_zones=3,5", "optics.depth_layers=4,8",
                                   "optics.rays_per_sample=16,64"])
def test_a_field_no_design_reads_is_refused_naming_it(field):
    with pytest.raises(ParameterError, match=field.split("=")[0]):
        check_grid(PINHOLE, parse_vary([field]))


def test_a_field_read_by_one_of_the_varied_levels_or_by_auto_is_allowed():
    assert check_grid(PINHOLE, parse_vary(["optics.model=pinhole,thin_lens", "optics.depth_layers=4,8"])) == []
    auto = PINHOLE.updated(optics=PINHOLE.optics.updated(model="auto"))
    assert check_grid(auto, parse_vary(["optics.psf_field_zones=3,5"])) == []
