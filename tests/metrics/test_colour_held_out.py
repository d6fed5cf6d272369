"""ΔE2000 that generalises: each Macbeth patch scored through the colour matrix fitted to the other
23 (held out) beside the matrix fitted to all 24 (fitted, training patches), on flat-fielded patch
means. Oracle: a sensor whose spectral responses are an exact linear transform of the CIE 1931
observer reproduces every colour, fitted or not; a noisy real camera does worse on held-out colours."""
from __future__ import annotations

import numpy as np
import pytest

from workbench import spectrum_csv
from workbench.metrics.frame import colour_error
from workbench.project import load_project


@pytest.fixture(scope="module")
def small():
    p = load_project("paper_camera")
    return p.updated(sensor=p.sensor.updated(rows=120, cols=160))


def observer_sensor_csv(folder) -> str:
    """sensors/observer_rgb.csv under `folder`: R, G, B = a mixing of x̄ȳz̄ (an invertible 3×3), per
    photon (÷ λ, so the photon-counting pixel integrates x̄ȳz̄ against energy), scaled into [0, 1]."""
    from workbench.spectra import xyz_cmfs
    wl = np.arange(380.0, 781.0, 5.0)
    mix = np.array([[0.9, 0.3, 0.0], [0.2, 1.0, 0.1], [0.0, 0.1, 1.2]])     # columns: R, G, B from X, Y, Z
    qe = (xyz_cmfs(wl) @ mix) / wl[:, None]
    qe /= qe.max()
    path = folder / "sensors" / "observer_rgb.csv"
    path.parent.mkdir(parents=True)
    path.write_text("wavelength_nm,R,G,B\n" +
                    "".join(f"{w:g},{r:.9g},{g:.9g},{b:.9g}\n" for w, (r, g, b) in zip(wl, qe)))
    return "sensors/observer_rgb.csv"


def test_a_sensor_that_sees_like_the_cie_observer_has_no_colour_error_fitted_or_held_out(small, tmp_path,
                                                                                          monkeypatch):
    monkeypatch.setattr(spectrum_csv, "RESOURCES", tmp_path)
    p = small.updated(scene=small.scene.updated(wavelengths=small.scene.wavelengths.updated(
        start_nm=380.0, stop_nm=780.0, step_nm=5.0)),
        sensor=small.sensor.updated(filter_file=observer_sensor_csv(tmp_path), photodiode_qe_file=None,
                                    ir_cut_file=None, noise_flag=0, bit_depth=16),
        isp=small.isp.updated(illuminant_correction="none"))   # D65, the fit's own light: no white balance to err
    assert p.optics.off_axis == "cos4th"                     # the fall-off is on: the flat field takes it out
    got = colour_error(p)
    print(f"\nCIE-observer sensor: ΔE2000 fitted mean {got['fitted']['mean']:.4f} max {got['fitted']['max']:.4f}; "
          f"held out mean {got['held_out']['mean']:.4f} max {got['held_out']['max']:.4f}")
    assert got["fitted"]["max"] < 0.05 and got["held_out"]["max"] < 0.05


def test_held_out_colours_are_no_better_than_the_fitted_ones_on_a_noisy_camera(small):
    got = colour_error(small)
    fitted, held = got["fitted"], got["held_out"]
    print(f"\nsmall paper camera: ΔE2000 held out mean {held['mean']:.3f} max {held['max']:.3f}; fitted (training) "
          f"mean {fitted['mean']:.3f} max {fitted['max']:.3f}; sRGB output {got['srgb_output']['mean']:.3f}")
    assert held["mean"] >= fitted["mean"] and held["max"] >= fitted["max"]
    assert sum(h >= f - 1e-9 for h, f in zip(held["patches"], fitted["patches"])) >= 18


def test_lens_fall_off_is_flat_fielded_out_of_the_colour_error(small):
    """cos⁴ fall-off on or off: the flat-fielded ΔE barely moves; the sRGB output's does (12 µm pixels:
    the paper camera's 44° field on the small sensor)."""
    wide = small.updated(sensor=small.sensor.updated(pixel_pitch_um=12.0))
    on = colour_error(wide)
    off = colour_error(wide.updated(optics=wide.optics.updated(off_axis="none")))
    print(f"\nfall-off on / off: fitted {on['fitted']['mean']:.3f} / {off['fitted']['mean']:.3f}, held out "
          f"{on['held_out']['mean']:.3f} / {off['held_out']['mean']:.3f}, sRGB output {on['srgb_output']['mean']:.3f}"
          f" / {off['srgb_output']['mean']:.3f}")
    for kind in ("fitted", "held_out"):
        assert on[kind]["mean"] == pytest.approx(off[kind]["mean"], abs=0.05), kind
    assert on["srgb_output"]["mean"] - off["srgb_output"]["mean"] > 0.2


def test_a_leave_one_out_fit_never_sees_its_patch():
    """The fit without patch k equals a least-squares fit to the other 23 done here; it differs from
    the full fit."""
    from workbench.isp.color import fit_sensor_to_xyz, macbeth_responses
    wl = np.arange(400.0, 701.0, 10.0)
    qe = np.stack([np.exp(-0.5 * ((wl - c) / 30.0) ** 2) for c in (600.0, 540.0, 460.0)], axis=1)
    S, s_white, X, x_white = macbeth_responses(qe, wl)
    S, X = S / s_white.max(), X / x_white[1]
    for k in (0, 14, 23):
        keep = np.arange(24) != k
        mine = np.linalg.lstsq(S[keep], X[keep], rcond=None)[0]
        np.testing.assert_allclose(fit_sensor_to_xyz(qe, wl, leave_out=k).matrix, mine, rtol=1e-8, atol=1e-10)
        assert not np.allclose(fit_sensor_to_xyz(qe, wl, leave_out=k).matrix, fit_sensor_to_xyz(qe, wl).matrix)
