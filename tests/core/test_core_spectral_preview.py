"""The irradiance preview (spectra → sRGB for display) against colour-science's own path: XYZ from
the CIE 1931 CMFs, colour.XYZ_to_RGB into sRGB, clipping and colour.cctf_encoding."""
import colour
import numpy as np
import pytest

from workbench import spectra
from workbench.previews import spectral_to_srgb


def colour_science_preview(photons, wavelengths_nm, percentile=99.0):
    xyz = spectra.xyz_from_photons(photons.reshape(-1, photons.shape[-1]).astype(np.float64), wavelengths_nm)
    xyz = xyz / np.percentile(xyz[:, 1], percentile)
    rgb = np.clip(colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False), 0, 1)
    return colour.cctf_encoding(rgb, function="sRGB").reshape(*photons.shape[:2], 3)


@pytest.mark.parametrize("dtype,atol", [(np.float64, 2e-7), (np.float32, 2e-6)])
@pytest.mark.parametrize("wavelengths_nm", [np.linspace(400, 700, 16), np.arange(400.0, 701.0, 10.0),
                                            np.array([450.0, 550.0, 610.0])])
def test_preview_equals_colour_science(dtype, atol, wavelengths_nm):
    rng = np.random.default_rng(wavelengths_nm.size)
    photons = (rng.lognormal(0.0, 1.5, (23, 31, wavelengths_nm.size)) * 1e17).astype(dtype)
    got = spectral_to_srgb(photons, wavelengths_nm)
    assert got.dtype == np.float32 and got.shape == (23, 31, 3)
    np.testing.assert_allclose(got, colour_science_preview(photons, wavelengths_nm), atol=atol)


def test_a_black_frame_previews_black():
    assert not spectral_to_srgb(np.zeros((4, 5, 16), np.float32), np.linspace(400, 700, 16)).any()
