"""The compiled per-pixel ISP kernels against plain numpy float64 references of the same formulas:
the sRGB encoding against the exact curve at every float32 step near the knee and across [0, 1],
the colour pass (K×3 products, neutral highlights, the maximum) on random K-channel images."""
import numpy as np
import pytest

from workbench.errors import InvalidValueError
from workbench.isp.color import srgb_encode
from workbench.isp.process import HIGHLIGHT_START, SATURATED_FRACTION, colour_transform


def exact_srgb(x):
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def test_srgb_encoding_is_within_float32_rounding_of_the_curve():
    rng = np.random.default_rng(0)
    knee = np.float32(0.0031308)
    around_knee = np.nextafter(knee, np.float32(1), dtype=np.float32) + np.arange(-2000, 2000, dtype=np.float32) * np.float32(1e-9)
    x = np.concatenate([rng.uniform(0, 1, 200_000), np.geomspace(1e-8, 1, 5000), around_knee]).astype(np.float32)
    err = np.abs(srgb_encode(x).astype(np.float64) - exact_srgb(x))
    assert err.max() < 2e-7, x[err.argmax()]
    assert srgb_encode(np.array([0, 1, -3, 7, np.inf], np.float32)).tolist() == [0, 1, 0, 1, 1]
    assert np.isnan(srgb_encode(np.array([np.nan], np.float32)))[0]          # left for the ISP to refuse


def test_scale_multiplies_before_the_curve():
    x = np.linspace(0, 3, 1001, dtype=np.float32)
    np.testing.assert_allclose(srgb_encode(x, 0.25), exact_srgb(x * np.float32(0.25)), atol=2e-7)


def reference_colour(linear, to_rgb, neutral):
    lin = linear.astype(np.float64)
    rgb = lin @ to_rgb
    if neutral:
        t = np.clip((lin.max(axis=-1) - HIGHLIGHT_START) / (SATURATED_FRACTION - HIGHLIGHT_START), 0, 1)
        w = (t * t * (3 - 2 * t))[..., None]
        rgb = rgb + w * (rgb.max(axis=-1, keepdims=True) - rgb)
    return rgb


@pytest.mark.parametrize("k", [3, 4])
@pytest.mark.parametrize("neutral", [False, True])
def test_colour_pass_matches_numpy(k, neutral):
    """float32 sums of K products: within a few float32 roundings of the float64 reference."""
    rng = np.random.default_rng(k + 2 * neutral)
    linear = rng.uniform(0, 1, (37, 53, k)).astype(np.float32)
    linear[::5, ::3] = rng.uniform(0.85, 1.0, (k,)).astype(np.float32)      # near saturation
    to_rgb = rng.normal(0, 1, (k, 3))
    rgb, peak = colour_transform(linear, to_rgb, neutral)
    want_rgb = reference_colour(linear, to_rgb, neutral)
    assert rgb.dtype == np.float32 and rgb.shape == (37, 53, 3)
    scale = np.abs(linear).sum(axis=-1, keepdims=True) * np.abs(to_rgb).max()   # the sums' magnitude
    assert np.all(np.abs(rgb - want_rgb) <= 1e-6 * scale)
    assert peak == pytest.approx(want_rgb.max(), rel=1e-6)


def test_the_fused_pass_encodes_what_the_two_passes_do():
    rng = np.random.default_rng(9)
    linear = rng.uniform(0, 1.2, (29, 31, 3)).astype(np.float32)
    to_rgb = rng.normal(0.4, 0.3, (3, 3))
    rgb, peak = colour_transform(linear, to_rgb, True)
    fused, fused_peak = colour_transform(linear, to_rgb, True, encode=True)
    np.testing.assert_array_equal(fused, srgb_encode(rgb))
    assert fused_peak == peak


def reference_white_world(flat, to_ics, saturated, fraction):
    """The white-world statistic by its definition, in float64 numpy with masked copies."""
    flat = flat.astype(np.float64)
    valid = np.all(flat < saturated, axis=1)
    if not valid.any():
        valid = np.ones(len(flat), bool)
    ics = flat[valid] @ to_ics
    plane = ics[:, np.argmax(ics.max(axis=0))]
    return ics[plane >= fraction * plane.max()].mean(axis=0)


@pytest.mark.parametrize("k", [1, 3, 4])
@pytest.mark.parametrize("rows", [1, 7, 480])
def test_white_world_statistic_matches_its_definition(k, rows, monkeypatch):
    """Both passes (over row blocks, threaded on a large frame) against the masked numpy mean,
    with saturated and NaN pixels left out; the same gains on one thread as on two."""
    from workbench.isp.illuminant import illuminant_gains
    rng = np.random.default_rng(k * 1000 + rows)
    linear = rng.uniform(0, 1, (rows, 640, k)).astype(np.float32)
    linear[rng.random((rows, 640)) < 0.05] = 1.0                        # clipped pixels
    linear[rng.random((rows, 640)) < 0.001, 0] = np.nan                 # e.g. a dead pixel's NaN
    to_ics = rng.uniform(0.1, 1.0, (k, 3))
    white = np.array([0.95, 1.0, 1.09])
    for fraction in (0.3, 0.7, 0.95):
        means = reference_white_world(linear.reshape(-1, k), to_ics, SATURATED_FRACTION, fraction)
        expected = (white / white[1]) * (means[1] / means)
        gains, notes = illuminant_gains(linear, to_ics, "white_world", white, white_world_fraction=fraction,
                                        saturated=SATURATED_FRACTION)
        np.testing.assert_allclose(gains, expected, rtol=1e-12)
        assert notes == []
        monkeypatch.setenv("WORKBENCH_THREADS", "1")
        assert np.array_equal(illuminant_gains(linear, to_ics, "white_world", white, white_world_fraction=fraction,
                                               saturated=SATURATED_FRACTION)[0], gains)
        monkeypatch.delenv("WORKBENCH_THREADS")


def test_white_world_on_an_all_saturated_frame_uses_every_pixel_and_says_so():
    from workbench.isp.illuminant import illuminant_gains
    linear = np.full((4, 6, 3), 1.0, np.float32)
    linear[..., 0] = 1.5
    gains, notes = illuminant_gains(linear, np.eye(3), "white_world", np.ones(3), saturated=SATURATED_FRACTION)
    np.testing.assert_allclose(gains, [1 / 1.5, 1.0, 1.0])
    assert any("every pixel is saturated" in n for n in notes)


def reference_gray_pixels(flat, to_ics, white, saturated):
    """The gray-pixels statistic by its definition, in float64 numpy with masked copies: the
    sampled unsaturated pixels, gray world, then rounds of gray world over the lit pixels whose
    corrected chromaticity lies within each round's tolerance of the white's."""
    from workbench.isp.illuminant import GREY_PIXEL_MIN_SHARE, GREY_PIXEL_SAMPLES, GREY_PIXEL_TOLERANCES
    sample = flat[::max(1, len(flat) // GREY_PIXEL_SAMPLES)].astype(np.float64)
    valid = np.all(sample < saturated, axis=1)
    ics = sample[valid] @ to_ics
    gains = (white / white[1]) * (ics.mean(axis=0)[1] / ics.mean(axis=0))
    corrected = ics * gains
    lit = corrected.sum(axis=1) > 0.02 * np.percentile(corrected.sum(axis=1), 99, method="higher")
    for tolerance in GREY_PIXEL_TOLERANCES:
        corrected = ics * gains
        chroma = corrected / corrected.sum(axis=1, keepdims=True)
        grey = lit & np.all(np.abs(chroma - white / white.sum()) < tolerance, axis=1)
        if grey.sum() < GREY_PIXEL_MIN_SHARE * len(ics):
            break
        means = ics[grey].mean(axis=0)
        gains = (white / white[1]) * (means[1] / means)
    return gains


@pytest.mark.parametrize("seed", range(4))
def test_gray_pixels_statistic_matches_its_definition(seed):
    """The compiled rounds against the numpy definition on a frame of a few coloured patches,
    noisy greys, dark and clipped pixels, seen under a tinted light."""
    from workbench.isp.illuminant import illuminant_gains
    rng = np.random.default_rng(seed)
    patches = np.concatenate([rng.uniform(0.05, 0.9, (6, 3)), np.repeat(rng.uniform(0.1, 0.9, (4, 1)), 3, axis=1)])
    linear = patches[rng.integers(0, len(patches), (120, 160))] * rng.uniform(0.6, 1.4, 3)   # the light's tint
    linear += rng.normal(0, 0.01, linear.shape)
    linear[rng.random((120, 160)) < 0.05] = 1.0                          # clipped
    linear[rng.random((120, 160)) < 0.05] = 0.001                        # dark
    linear = np.clip(linear, 0, 1).astype(np.float32)
    to_ics = rng.uniform(0.1, 1.0, (3, 3)) + np.eye(3)
    white = np.array([0.95, 1.0, 1.09])
    gains, _ = illuminant_gains(linear, to_ics, "gray_pixels", white, saturated=SATURATED_FRACTION)
    expected = reference_gray_pixels(linear.reshape(-1, 3), to_ics, white, SATURATED_FRACTION)
    np.testing.assert_allclose(gains, expected, rtol=1e-6)


@pytest.mark.parametrize("n", [1, 2, 99, 100, 101, 8192, 8305])
def test_gray_pixels_percentile_is_numpys_higher_rank(n):
    from workbench.isp.illuminant import _percentile_99
    values = np.random.default_rng(n).lognormal(0, 2, n)
    assert _percentile_99(values) == np.percentile(values, 99, method="higher")


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint16])
def test_raw_is_the_clipped_dn_fraction_and_refuses_nan_and_inf(dtype):
    from workbench.isp.process import _raw
    from workbench.sensor.image import SensorImage
    dn = (np.random.default_rng(0).uniform(-20, 300, (37, 53))).clip(0 if dtype == np.uint16 else -20).astype(dtype)

    def image(values):
        return SensorImage(electrons=values, volts=values, dn=values, cfa_tile=np.zeros((1, 1), int),
                           channel_names=["M"], pattern="MONO", qe=np.zeros((0, 1)), wavelengths_nm=np.zeros(0),
                           exposure_s=0.01, max_dn=255.0, meta={})
    raw = _raw(image(dn))
    assert raw.dtype == np.float32
    np.testing.assert_allclose(raw, np.clip(dn.astype(np.float64) / 255.0, 0, 1), rtol=2.5e-7, atol=0)   # two float32 roundings
    if dtype != np.uint16:
        for bad in (np.nan, np.inf, -np.inf):
            spoiled = dn.copy()
            spoiled[5, 7] = bad
            with pytest.raises(InvalidValueError, match="NaN or Inf"):
                _raw(image(spoiled))
