"""Colour: the sRGB curve and matrix against colour-science, the Macbeth fit and its conditioning."""
import colour
import numpy as np
import pytest

from isp_synthetic import WL, camera_like_qe, cie_like_qe
from workbench.isp.color import (
    ColourFitError,
    fit_sensor_to_xyz,
    macbeth_responses,
    srgb_encode,
    srgb_white_xyz,
    xyz_to_linear_srgb_matrix,
    xyz_to_srgb_linear,
)


def test_srgb_encode_matches_colour_science():
    x = np.concatenate([np.linspace(0, 0.01, 2001), np.linspace(0, 1, 10001)]).astype(np.float32)
    ref = colour.cctf_encoding(x.astype(np.float64), function="sRGB")
    out = srgb_encode(x)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, ref, atol=2e-6)
    np.testing.assert_array_equal(srgb_encode(np.array([-1.0, 2.0, np.float32(1.0)])), [0.0, 1.0, 1.0])


def test_xyz_to_srgb_matrix_matches_colour_science():
    rng = np.random.default_rng(1)
    xyz = rng.random((50, 3))
    ref = colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)
    np.testing.assert_allclose(xyz_to_srgb_linear(xyz), ref, atol=1e-5)
    np.testing.assert_allclose(xyz_to_linear_srgb_matrix() @ srgb_white_xyz(), np.ones(3), atol=1e-12)
    assert srgb_white_xyz()[1] == pytest.approx(1.0, abs=1e-4)   # the standard's rounded matrix


def test_colorimetric_sensor_gives_exact_fit():
    """A sensor with QE = CMF·λ₀/λ counts photons exactly as XYZ weighs energy: residual ≈ 0."""
    from workbench.spectra import xyz_cmfs
    qe = xyz_cmfs(WL) * (555.0 / WL)[:, None]
    fit = fit_sensor_to_xyz(qe, WL)
    assert fit.residual_rms < 1e-10 and fit.ridge == 0.0 and fit.notes == ()
    S, s_white, X, x_white = macbeth_responses(qe, WL)
    np.testing.assert_allclose((S / s_white.max()) @ fit.matrix, X / x_white[1], atol=1e-10)


@pytest.mark.parametrize("qe_fn,max_rms", [(cie_like_qe, 0.003), (camera_like_qe, 0.02)])
def test_fit_quality_and_cache(qe_fn, max_rms):
    qe = qe_fn()
    fit = fit_sensor_to_xyz(qe, WL)
    print(f"{qe_fn.__name__}: condition {fit.condition:.3g}, residual rms {fit.residual_rms:.2e}")
    assert fit.matrix.shape == (3, 3) and np.all(np.isfinite(fit.matrix))
    assert fit.residual_rms < max_rms and fit.ridge == 0.0
    assert fit_sensor_to_xyz(qe.copy(), WL.copy()) is fit          # cached per QE array
    assert not fit.matrix.flags.writeable


def test_identical_channels_are_refused():
    qe = cie_like_qe()
    qe[:, 2] = qe[:, 1]
    with pytest.raises(ColourFitError, match="independent"):
        fit_sensor_to_xyz(qe, WL)


def test_mono_and_dead_channels_are_refused():
    with pytest.raises(ColourFitError, match="at least 3"):
        fit_sensor_to_xyz(cie_like_qe()[:, :1], WL)
    qe = cie_like_qe()
    qe[:, 0] = 0.0
    with pytest.raises(ColourFitError, match="do not respond"):
        fit_sensor_to_xyz(qe, WL)


def test_nearly_identical_channels_are_regularised_with_a_note():
    qe = cie_like_qe()
    qe[:, 2] = qe[:, 1] * (1.0 + 1e-5 * np.linspace(-1, 1, WL.size))
    fit = fit_sensor_to_xyz(qe, WL, max_condition=1e4)
    assert fit.condition > 1e4 and fit.ridge > 0
    assert fit.notes and "regularised" in fit.notes[0]
    assert np.all(np.isfinite(fit.matrix)) and np.abs(fit.matrix).max() < 1e3


def test_rgbw_with_dependent_white_is_regularised():
    """W = R + G + B exactly: rank 3 of 4 channels — fitted with a ridge, and still accurate."""
    qe3 = camera_like_qe()
    qe = np.column_stack([qe3, qe3.sum(axis=1)])
    fit = fit_sensor_to_xyz(qe, WL)
    assert fit.matrix.shape == (4, 3) and fit.ridge > 0 and fit.notes
    assert fit.residual_rms < 0.03


def test_bad_qe_is_refused():
    with pytest.raises(ValueError, match="Nλ×K"):
        fit_sensor_to_xyz(np.ones((5, 3)), WL)
    qe = cie_like_qe()
    qe[3, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        fit_sensor_to_xyz(qe, WL)
