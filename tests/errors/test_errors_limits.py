"""Inputs past what can be simulated get a message naming the setting, before any large allocation:
a scene just beyond the focal length (magnification ~500: a 24×32 image asked 12 GiB for its
diffraction blur, and 32 GiB for a ray-traced lens's Airy kernel), a full well below one electron
(it ran and reported −340 dB), and a JSON number of more digits than Python converts (it was an
'internal error')."""
import pytest

from workbench.errors import InputFileError, WorkbenchError
from workbench.project import PROJECTS_DIR, load_project, project_from_dict


def _small(**optics):
    p = load_project("uniform_d65_isetcam_pixel")
    return p.updated(sensor=p.sensor.updated(rows=24, cols=32), optics=p.optics.updated(**optics))


@pytest.mark.parametrize("optics, distance_m", [
    ({"model": "diffraction_limited", "focal_length_mm": 50.0}, 0.0501),
    ({"model": "raytrace", "lens_file": "dgauss.50mm", "raytrace_diffraction": True}, 0.0505)])
def test_a_blur_wider_than_the_image_is_refused_naming_the_distance(optics, distance_m):
    import resource

    from workbench.pipeline import Pipeline
    p = _small(**optics)
    p = p.updated(scene=p.scene.updated(distance_m=distance_m))
    import os
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    in_use = int(open("/proc/self/statm").read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    cap = in_use + 6 * 2 ** 30                 # 6 GiB more than this process maps: the 12–32 GiB asks fail under it
    resource.setrlimit(resource.RLIMIT_AS, (cap if hard == resource.RLIM_INFINITY else min(cap, hard), hard))
    try:
        with pytest.raises(WorkbenchError, match=r"blur is .* samples in radius.*scene\.distance_m"):
            Pipeline(p).run()
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def test_an_ordinary_blur_is_not_refused():
    from workbench.optics.formation.fourier import pad_width
    assert pad_width((480, 640), 30.0) == 80                  # 1/8 of the larger side
    assert pad_width((24, 32), 200.0) == 200                   # wider than the image, but small: simulated


def test_a_full_well_below_one_electron_is_refused():
    p = load_project("paper_camera")
    with pytest.raises(ValueError, match=r"at least 1 electron.*voltage_swing_V"):
        p.sensor.updated(voltage_swing_V=1e-20)


def test_a_number_of_too_many_digits_is_a_file_error(tmp_path):
    f = tmp_path / "p.json"
    f.write_text('{"name": "x", "sensor": {"rows": ' + "9" * 5000 + "}}")
    with pytest.raises(InputFileError, match="fewer digits"):
        load_project(f)


def test_a_psf_grid_far_out_of_focus_names_the_focus():
    """dgauss.50mm focused at 52 mm, the scene at 5 m: the spot misses the PSF grid (it was a NaN
    image and 'please report')."""
    from workbench.pipeline import Pipeline
    p = _small(model="psf_grid", lens_file="dgauss.50mm", focus_distance_m=0.052)
    p = p.updated(scene=p.scene.updated(distance_m=5.0))
    with pytest.raises(WorkbenchError, match=r"outside its .*grid.*optics\.focus_distance_m"):
        Pipeline(p).run()


@pytest.mark.parametrize("flag", [True, False, 2.0, "2"])
def test_noise_flag_is_a_whole_number(flag):
    p = load_project("paper_camera")
    with pytest.raises(ValueError, match="noise_flag must be one of"):
        p.sensor.updated(noise_flag=flag)
    assert p.sensor.updated(noise_flag=1).noise_flag == 1


@pytest.mark.parametrize("field, value, message", [
    ("lamp_flux_lm", 1e-35, "greater than or equal to 1"), ("headlight_cd", 1e-36, "greater than or equal to 1"),
    ("taillight_cd", 1e-36, "greater than or equal to 0.1"), ("sky_luminance_cd_m2", 1e-40, "0 .no sky glow. or at least")])
def test_a_vanishing_night_light_is_refused_naming_it(field, value, message):
    """Below ~1e-34 the lights' spectra underflow float32 and Mitsuba stopped with 'no probability
    mass found', reported as an internal error."""
    from workbench.errors import ParameterError
    data = _project_dict("city_night")
    data["render"]["world"]["night"][field] = value
    with pytest.raises(ParameterError, match=rf"render\.world\.night\.{field}: .*{message}"):
        project_from_dict(data)
    data["render"]["world"]["night"].update({field: 0.0 if field == "sky_luminance_cd_m2" else 20.0})
    project_from_dict(data)                    # no glow, or an ordinary light: loads


def test_a_focal_length_wider_than_a_rectilinear_camera_names_it():
    """10⁻³⁰⁰ mm made the chart 180° wide, refused by the scene without naming a setting; 10⁻⁶ mm
    ran with negative irradiance at the edges (the exact fall-off cancelled)."""
    from workbench.errors import ParameterError
    data = _project_dict("uniform_d65_isetcam_pixel")
    for f_mm in (1e-300, 1e-6):
        data["optics"]["focal_length_mm"] = f_mm
        with pytest.raises(ParameterError, match=r"optics\.focal_length_mm: .*spans 1[78]\d.*less than 179°"):
            project_from_dict(data)
    data["optics"]["focal_length_mm"] = 0.01
    project_from_dict(data)                     # 170° across 0.25 mm: allowed


def test_chart_wavelengths_the_eye_cannot_see_are_refused():
    """A chart at 1000–1100 nm is scaled to a luminance it cannot have (was 'the spectrum has no
    power where the eye is sensitive' from the scene stage, naming no setting)."""
    from workbench.errors import ParameterError
    data = _project_dict("uniform_d65_isetcam_pixel")
    data["scene"]["wavelengths"].update(start_nm=1000.0, stop_nm=1100.0)
    with pytest.raises(ParameterError, match=r"scene\.wavelengths 1000–1100 nm: .*380–780 nm"):
        project_from_dict(data)
    data["scene"]["wavelengths"]["start_nm"] = 700.0
    project_from_dict(data)                     # reaches 700 nm: allowed


def _project_dict(name: str) -> dict:
    import json
    return json.loads((PROJECTS_DIR / f"{name}.json").read_text())
