"""Network inputs: exact raw packing for every CFA, fixed scaling."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.detect.representations import (
    input_channels, input_stride, network_input, pack_raw, packed_channel_names, packed_sites,
    raw_scaled, unpack_raw)
from workbench.errors import ParameterError
from workbench.isp import BLACK_LEVEL_KEY, ISPParams, sensor_image_to_srgb
from workbench.sensor import CFA_PATTERNS
from workbench.sensor.image import SensorImage


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_pack_unpack_round_trip_exact(pattern):
    mosaic = np.random.default_rng(1).random((6, 10)).astype(np.float32)
    packed = pack_raw(mosaic, pattern)
    assert packed.shape == (4, 3, 5)
    assert np.array_equal(unpack_raw(packed, pattern), mosaic)
    assert sorted(packed_sites(pattern)) == [(0, 0), (0, 1), (1, 0), (1, 1)]


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(CFA_PATTERNS), st.integers(1, 9), st.integers(1, 9), st.integers(0, 2**32 - 1))
def test_pack_unpack_round_trip_any_even_size(pattern, half_rows, half_cols, seed):
    mosaic = np.random.default_rng(seed).integers(0, 4096, (2 * half_rows, 2 * half_cols)).astype(np.uint16)
    packed = pack_raw(mosaic, pattern)
    assert packed.shape == (4, half_rows, half_cols) and packed.dtype == np.uint16
    assert np.array_equal(unpack_raw(packed, pattern), mosaic)


def test_plane_order_is_documented_one():
    for pattern in ("RGGB", "GRBG", "GBRG", "BGGR"):
        assert packed_channel_names(pattern) == ["R", "G", "G", "B"]
        (r0, c0), (r1, c1), (r2, c2), _ = packed_sites(pattern)
        assert r1 == r0 and c2 == c0          # G on the red row, then G on the red column
    assert packed_channel_names("RCCB") == ["R", "B", "C", "C"]
    assert packed_channel_names("RGBW") == ["R", "G", "B", "W"]
    assert packed_sites("MONO") == [(0, 0), (0, 1), (1, 0), (1, 1)]


def test_odd_mosaic_refused():
    with pytest.raises(ParameterError, match="even"):
        pack_raw(np.zeros((5, 4)), "RGGB")
    with pytest.raises(ParameterError, match="cfa_pattern"):
        pack_raw(np.zeros((4, 4)), "XYZW")


def _sensor_image(dn: np.ndarray, black_dn: float, max_dn: float = 255.0) -> SensorImage:
    wl = np.linspace(400, 700, 31)
    qe = np.stack([np.exp(-0.5 * ((wl - m) / 35) ** 2) for m in (600, 535, 455)], axis=1) * 0.5
    zeros = np.zeros_like(dn)
    return SensorImage(electrons=zeros, volts=zeros, dn=dn, cfa_tile=np.array([[0, 1], [1, 2]]),
                       channel_names=["R", "G", "B"], pattern="RGGB", qe=qe, wavelengths_nm=wl,
                       exposure_s=0.01, max_dn=max_dn, meta={BLACK_LEVEL_KEY: black_dn})


def test_fixed_scaling_keeps_exposure_differences():
    rng = np.random.default_rng(3)
    dn = np.rint(rng.uniform(16, 120, (8, 12))).astype(np.float32)
    dim, bright = _sensor_image(dn, 16.0), _sensor_image(2 * dn - 16, 16.0)
    x_dim, x_bright = network_input(dim, None, "raw"), network_input(bright, None, "raw")
    assert x_dim.shape == (4, 4, 6) and x_dim.dtype == np.float32
    np.testing.assert_allclose(x_dim, pack_raw((dn - 16) / (255 - 16), "RGGB"), rtol=1e-6)
    np.testing.assert_allclose(x_bright, 2 * x_dim, rtol=1e-5)       # no per-image normalisation
    params = ISPParams(illuminant_correction="none")
    lin_dim = network_input(dim, sensor_image_to_srgb(dim, params), "linear")
    lin_bright = network_input(bright, sensor_image_to_srgb(bright, params), "linear")
    assert lin_dim.shape == (3, 8, 12)
    np.testing.assert_allclose(lin_bright, 2 * lin_dim, rtol=1e-5, atol=1e-6)
    srgb = network_input(dim, sensor_image_to_srgb(dim, params), "srgb")
    assert srgb.shape == (3, 8, 12) and 0 <= srgb.min() and srgb.max() <= 1


def test_raw_scaling_clips_below_black():
    dn = np.array([[0, 16], [100, 255]], dtype=np.float32)
    np.testing.assert_allclose(raw_scaled(_sensor_image(dn, 16.0)), [[0, 0], [84 / 239, 1]], rtol=1e-6)


def test_strides_and_channels():
    assert (input_stride("raw"), input_stride("linear"), input_stride("srgb")) == (2, 1, 1)
    assert input_channels("raw", "RCCC") == 4 and input_channels("linear", "RCCC") == 2
    assert input_channels("linear", "RGBW") == 4 and input_channels("srgb", "MONO") == 3
    with pytest.raises(ParameterError, match="representation"):
        input_stride("jpeg")
