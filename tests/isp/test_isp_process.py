"""The ISP pipeline end to end on synthetic SensorImages."""
import colour
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from pydantic import ValidationError

from isp_synthetic import (
    BAYER_TILES, WL, camera_like_qe, cie_like_qe, macbeth_chart, patch_means, sensor_image,
)
from workbench.isp import ISPParams, sensor_image_to_srgb
from workbench.isp.color import macbeth_responses

D65_XY = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
NEUTRAL_5 = 21          # Macbeth 'neutral 5 (.70 D)'


def delta_e_2000(xyz, xyz_ref):
    return colour.delta_E(colour.XYZ_to_Lab(xyz, D65_XY), colour.XYZ_to_Lab(xyz_ref, D65_XY),
                          method="CIE 2000")


def _check_outputs(res, shape, k):
    h, w = shape
    assert res.raw.shape == (h, w) and res.linear.shape == (h, w, k) and res.srgb.shape == (h, w, 3)
    for arr in (res.raw, res.linear, res.srgb):
        assert arr.dtype == np.float32 and np.all(np.isfinite(arr))
        assert arr.min() >= 0.0 and arr.max() <= 1.0


@pytest.mark.parametrize("qe_fn,mean_bound,max_bound", [(cie_like_qe, 1.0, 3.0),
                                                         (camera_like_qe, 2.0, 4.0)])
@pytest.mark.parametrize("pattern", ["RGGB", "GBRG"])
def test_macbeth_delta_e(qe_fn, mean_bound, max_bound, pattern):
    """Macbeth chart under D65 through a synthetic sensor → ΔE2000 of the 24 patches."""
    qe = qe_fn()
    img, xyz_ref = macbeth_chart(qe)
    res = sensor_image_to_srgb(sensor_image(img, BAYER_TILES[pattern], "RGB", qe), ISPParams(illuminant_correction="none"))
    _check_outputs(res, img.shape[:2], 3)
    de_xyz = delta_e_2000(patch_means(res.xyz), xyz_ref)
    de_srgb = delta_e_2000(colour.sRGB_to_XYZ(patch_means(res.srgb)), xyz_ref)   # full pipeline
    print(f"\n{qe_fn.__name__} {pattern}: ΔE2000 XYZ mean {de_xyz.mean():.2f} max {de_xyz.max():.2f}; "
          f"sRGB mean {de_srgb.mean():.2f} max {de_srgb.max():.2f} (worst patch {de_srgb.argmax()})")
    assert de_xyz.mean() < mean_bound and de_xyz.max() < max_bound
    assert de_srgb.mean() < mean_bound and de_srgb.max() < max_bound


def _uniform_under(qe, illuminant, patch, level=0.6, shape=(16, 16)):
    S, s_white, _, _ = macbeth_responses(qe, WL, illuminant)
    return np.broadcast_to(S[patch] / S[patch].max() * level, (*shape, qe.shape[1]))


@pytest.mark.parametrize("method", ["gray_world", "white_world"])
def test_illuminant_correction_makes_grey_neutral(method):
    qe = camera_like_qe()
    grey = _uniform_under(qe, "A", NEUTRAL_5)
    si = sensor_image(grey, BAYER_TILES["RGGB"], "RGB", qe)
    plain = sensor_image_to_srgb(si, ISPParams(illuminant_correction="none")).srgb.reshape(-1, 3).mean(axis=0)
    assert plain[0] - plain[2] > 0.1                      # tungsten light renders orange
    res = sensor_image_to_srgb(si, ISPParams(illuminant_correction=method))
    rgb = res.srgb.reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(rgb, rgb[1], atol=2e-3)
    assert res.gains[1] == 1.0                            # the correction keeps Y (exposure)
    np.testing.assert_allclose(res.xyz[..., 1], sensor_image_to_srgb(si, ISPParams(illuminant_correction="none")).xyz[..., 1], rtol=1e-6)


def test_white_world_uses_the_bright_pixels():
    """Half a bright white, half a dim red, under tungsten: white world neutralises the white
    (the few demosaic-blended pixels at the border leave a small bias); gray world, pulled by
    the red, does not."""
    qe = camera_like_qe()
    white = _uniform_under(qe, "A", 18, level=0.9, shape=(16, 32))      # 'white 9.5'
    red = _uniform_under(qe, "A", 14, level=0.3, shape=(16, 32))        # 'red'
    si = sensor_image(np.concatenate([white, red], axis=1), BAYER_TILES["RGGB"], "RGB", qe)
    rgb = {m: sensor_image_to_srgb(si, ISPParams(illuminant_correction=m)).srgb[4:-4, 2:20].reshape(-1, 3).mean(axis=0)
           for m in ("white_world", "gray_world")}
    np.testing.assert_allclose(rgb["white_world"], rgb["white_world"][1], atol=6e-3)
    assert np.ptp(rgb["gray_world"]) > 0.1


def test_manual_gains_are_applied_in_xyz():
    qe = cie_like_qe()
    img, _ = macbeth_chart(qe)
    si = sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe)
    base = sensor_image_to_srgb(si, ISPParams(illuminant_correction="none"))
    res = sensor_image_to_srgb(si, ISPParams(illuminant_correction="manual", manual_gains=(0.5, 1.0, 2.0)))
    np.testing.assert_allclose(res.xyz, base.xyz * np.array([0.5, 1.0, 2.0], np.float32), rtol=1e-5, atol=1e-7)


def test_normalize_max_cancels_exposure_and_swing_keeps_it():
    qe = camera_like_qe()
    img, _ = macbeth_chart(qe, white_level=0.5)
    images = [sensor_image(img * s, BAYER_TILES["RGGB"], "RGB", qe, max_dn=1.0) for s in (0.25, 1.0)]
    swing = [sensor_image_to_srgb(si, ISPParams(normalize="swing")).srgb for si in images]
    peak = [sensor_image_to_srgb(si, ISPParams(normalize="max")).srgb for si in images]
    assert swing[1].mean() - swing[0].mean() > 0.15
    np.testing.assert_allclose(peak[0], peak[1], atol=1e-4)
    assert peak[1].max() == pytest.approx(1.0)


@pytest.mark.parametrize("tile,names,pattern", [
    ([[0, 1], [1, 1]], ["R", "C"], "RCCC"),
    ([[0]], ["M"], "MONO"),
])
def test_colourless_sensors_give_grey_with_note(tile, names, pattern):
    rng = np.random.default_rng(3)
    k = len(names)
    qe = np.stack([np.full(WL.size, 0.5)] * k, axis=1)
    img = rng.random((12, 14, k))
    res = sensor_image_to_srgb(sensor_image(img, tile, names, qe, pattern=pattern),
                      ISPParams(illuminant_correction="gray_world"))
    _check_outputs(res, (12, 14), k)
    assert res.xyz is None and res.colour_fit is None
    assert np.array_equal(res.srgb[..., 0], res.srgb[..., 1]) and np.array_equal(res.srgb[..., 1], res.srgb[..., 2])
    assert any("grey" in n for n in res.notes) and any("skipped" in n for n in res.notes)
    grey_k = names.index("C") if "C" in names else 0
    np.testing.assert_allclose(res.srgb[..., 0], colour.cctf_encoding(res.linear[..., grey_k]), atol=1e-5)


def test_rccb_and_rgbw_get_colour():
    """RCCB (C ≈ R+G+B) and RGBW sensors: a fitted 3- or 4-channel matrix gives colour."""
    rgb = camera_like_qe()
    for names, tile, qe in [(["R", "C", "B"], [[0, 1], [1, 2]], np.column_stack([rgb[:, 0], rgb.sum(1), rgb[:, 2]])),
                            (["R", "G", "B", "W"], [[0, 1], [3, 2]], np.column_stack([rgb, 0.8 * rgb.sum(1) + 0.05]))]:
        img, xyz_ref = macbeth_chart(qe)
        res = sensor_image_to_srgb(sensor_image(img, tile, names, qe), ISPParams(illuminant_correction="none"))
        _check_outputs(res, img.shape[:2], len(names))
        de = delta_e_2000(patch_means(res.xyz), xyz_ref)
        print(f"\n{''.join(names)}: ΔE2000 mean {de.mean():.2f} max {de.max():.2f}; notes {res.notes}")
        assert de.mean() < 3.0


def test_identical_rgb_channels_fall_back_to_grey_with_note():
    qe = cie_like_qe()
    qe[:, 2] = qe[:, 1]
    img, _ = macbeth_chart(qe)
    res = sensor_image_to_srgb(sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe), ISPParams(illuminant_correction="none"))
    _check_outputs(res, img.shape[:2], 3)
    assert res.xyz is None and any("independent" in n for n in res.notes)


def test_colour_transform_none_shows_sensor_rgb():
    qe = camera_like_qe()
    img = np.broadcast_to(np.array([0.2, 0.4, 0.6]), (8, 8, 3))
    res = sensor_image_to_srgb(sensor_image(img, BAYER_TILES["BGGR"], "RGB", qe, max_dn=4095.0),
                      ISPParams(colour_transform="none", illuminant_correction="none"))
    assert res.xyz is None
    np.testing.assert_allclose(res.srgb, colour.cctf_encoding(img), atol=1e-5)


@pytest.mark.parametrize("level", [0.0, 1.0])
@pytest.mark.parametrize("correction", ["none", "gray_world", "white_world"])
@pytest.mark.parametrize("normalize", ["swing", "max"])
def test_zero_and_saturated_images_are_finite(level, correction, normalize):
    qe = camera_like_qe()
    img = np.full((10, 12, 3), level)
    res = sensor_image_to_srgb(sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe),
                      ISPParams(illuminant_correction=correction, normalize=normalize))
    _check_outputs(res, (10, 12), 3)
    assert np.all(np.isfinite(res.xyz))
    if level == 0.0:
        assert res.srgb.max() == 0.0
    else:
        assert res.srgb.min() > 0.5


def test_default_params_are_a_cameras():
    """DESIGN.md §4's pipeline (bilinear, Macbeth/D65 matrix, gray-world family, sRGB; 'swing' keeps
    EV bias), with what a camera does beyond ISETCam: greys kept grey, blown highlights white."""
    p = ISPParams()
    assert (p.demosaic, p.colour_transform, p.illuminant_correction, p.normalize, p.highlights) == \
        ("bilinear", "macbeth_d65_wp", "gray_pixels", "swing", "neutral")


@pytest.mark.parametrize("qe_fn", [cie_like_qe, camera_like_qe])
def test_white_preserving_fit_maps_white_to_white_and_stays_close(qe_fn):
    from workbench.isp.color import fit_sensor_to_xyz
    qe = qe_fn()
    S, s_white, X, x_white = macbeth_responses(qe, WL, "D65")
    wp = fit_sensor_to_xyz(qe, WL, preserve_white=True)
    lsq = fit_sensor_to_xyz(qe, WL)
    np.testing.assert_allclose((s_white / s_white.max()) @ wp.matrix, x_white / x_white[1], rtol=1e-10)
    free = (s_white / s_white.max()) @ lsq.matrix
    print(f"\n{qe_fn.__name__}: unconstrained white → {free / free[1]} (x_white {x_white / x_white[1]})")
    assert wp.residual_rms < 1.5 * lsq.residual_rms + 1e-4      # the constraint costs little elsewhere


def test_clipped_highlights_render_white_and_are_left_out_of_the_white_balance():
    """A white that saturates every channel renders neutral white (the clipped triple through the
    matrix is pink); the saturated pixels do not steer gray world; unsaturated colours keep theirs."""
    qe = camera_like_qe()
    img, _ = macbeth_chart(qe, white_level=2.0)                 # white and neutral 8 clip
    img = np.clip(img, 0.0, 1.0)
    si = sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe)
    clip = sensor_image_to_srgb(si, ISPParams(illuminant_correction="none", highlights="clip"))
    neutral = sensor_image_to_srgb(si, ISPParams(illuminant_correction="none"))
    white = 18
    assert np.ptp(patch_means(clip.srgb)[white]) > 0.02                 # clipped: not neutral
    np.testing.assert_allclose(patch_means(neutral.srgb)[white], 1.0, atol=1e-3)
    dark = patch_means(img).max(axis=1) < 0.85                          # no channel near saturation
    assert dark.sum() >= 8
    np.testing.assert_allclose(patch_means(neutral.srgb)[dark], patch_means(clip.srgb)[dark], atol=1e-6)
    gains = sensor_image_to_srgb(si, ISPParams(illuminant_correction="gray_world")).gains
    unclipped = sensor_image(np.where(img.max(axis=2, keepdims=True) >= 0.98, 0.0, img)[:, :, :],
                             BAYER_TILES["RGGB"], "RGB", qe)
    np.testing.assert_allclose(gains, sensor_image_to_srgb(unclipped, ISPParams(illuminant_correction="gray_world"))
                               .gains, rtol=0.02)


def test_gray_pixels_keeps_the_greys_of_a_coloured_scene_grey():
    """On the Macbeth chart under D65 (whose mean is not grey) the right white balance is none:
    gray_pixels stays within 3 % of it (the greys are not spectrally flat) and gray world does not;
    under tungsten light it finds the grey patch's colour."""
    for qe in (camera_like_qe(), cie_like_qe()):
        img, _ = macbeth_chart(qe, white_level=0.9)
        si = sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe)
        pixels = sensor_image_to_srgb(si, ISPParams(illuminant_correction="gray_pixels")).gains
        world = sensor_image_to_srgb(si, ISPParams(illuminant_correction="gray_world")).gains
        assert np.abs(pixels - 1).max() < 0.03 < np.abs(world - 1).max(), (pixels, world)
    qe = camera_like_qe()
    grey = sensor_image(_uniform_under(qe, "A", NEUTRAL_5), BAYER_TILES["RGGB"], "RGB", qe)
    srgb = sensor_image_to_srgb(grey, ISPParams(illuminant_correction="gray_pixels")).srgb.reshape(-1, 3).mean(axis=0)
    assert np.ptp(srgb) < 0.01


def test_bad_input_is_refused():
    qe = camera_like_qe()
    si = sensor_image(np.zeros((6, 6, 3)), BAYER_TILES["RGGB"], "RGB", qe)
    si.dn[2, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sensor_image_to_srgb(si)
    si = sensor_image(np.zeros((6, 6, 3)), BAYER_TILES["RGGB"], "RGB", qe[:, :2])
    with pytest.raises(ValueError, match="qe"):
        sensor_image_to_srgb(si)
    with pytest.raises(ValidationError, match="demosaic"):
        ISPParams(demosaic="nearest")
    with pytest.raises(ValidationError, match="manual_gains"):
        ISPParams(manual_gains=(1.0, -1.0, 1.0))
    with pytest.raises(ValidationError, match="normalize"):
        ISPParams(normalize="auto")


def test_a_non_finite_colour_matrix_is_refused_before_the_pixels(monkeypatch):
    """The raw image is finite and in [0, 1], so only the matrix can make a pixel NaN or Inf."""
    from workbench.isp import process
    monkeypatch.setattr(process, "xyz_to_linear_srgb_matrix", lambda: np.full((3, 3), np.nan))
    si = sensor_image(np.full((6, 6, 3), 0.5), BAYER_TILES["RGGB"], "RGB", camera_like_qe())
    with pytest.raises(ValueError, match="colour matrix .* not finite"):
        sensor_image_to_srgb(si)


def test_menon_on_bayer_runs_through_pipeline():
    qe = cie_like_qe()
    img, xyz_ref = macbeth_chart(qe)
    res = sensor_image_to_srgb(sensor_image(img, BAYER_TILES["GRBG"], "RGB", qe), ISPParams(demosaic="menon2007", illuminant_correction="none"))
    _check_outputs(res, img.shape[:2], 3)
    assert delta_e_2000(patch_means(res.xyz), xyz_ref).mean() < 1.0


def test_black_level_is_subtracted_from_linear_not_raw():
    qe = camera_like_qe()
    img = np.broadcast_to(np.array([0.2, 0.4, 0.6]), (8, 8, 3))
    black_dn, max_dn = 64.0, 1023.0
    si = sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe, max_dn=max_dn)
    si.dn = (si.dn * (max_dn - black_dn) / max_dn + black_dn).astype(np.float32)   # offset recorded
    si.meta["black_level_dn"] = black_dn
    res = sensor_image_to_srgb(si, ISPParams(illuminant_correction="none"))
    np.testing.assert_allclose(res.linear, img, atol=1e-5)
    assert res.raw.min() == pytest.approx((0.2 * (max_dn - black_dn) + black_dn) / max_dn, abs=1e-6)
    si.meta["black_level_dn"] = max_dn
    with pytest.raises(ValueError, match="black_level_dn"):
        sensor_image_to_srgb(si)


def test_missing_qe_falls_back_to_sensor_rgb_with_note():
    img = np.broadcast_to(np.array([0.2, 0.4, 0.6]), (8, 8, 3))
    si = sensor_image(img, BAYER_TILES["RGGB"], "RGB", np.zeros((0, 3)), wl=np.zeros(0))
    res = sensor_image_to_srgb(si, ISPParams(illuminant_correction="none"))
    assert res.xyz is None and any("no QE" in n for n in res.notes)
    np.testing.assert_allclose(res.srgb, colour.cctf_encoding(img), atol=1e-5)


def test_gray_world_cost_on_the_macbeth_chart():
    """Gray world assumes the scene averages to grey; the Macbeth chart nearly does (report ΔE)."""
    qe = cie_like_qe()
    img, xyz_ref = macbeth_chart(qe)
    res = sensor_image_to_srgb(sensor_image(img, BAYER_TILES["RGGB"], "RGB", qe),
                               ISPParams(illuminant_correction="gray_world"))
    de = delta_e_2000(patch_means(res.xyz), xyz_ref)
    print(f"\ngray world on the Macbeth chart under D65: gains {np.round(res.gains, 3)}, "
          f"ΔE2000 mean {de.mean():.2f} max {de.max():.2f}")
    assert np.all(np.abs(res.gains - 1) < 0.25) and de.mean() < 8


PATTERNS = {   # tile, channel names, QE columns (from the camera-like R, G, B curves)
    "RGGB": ([[0, 1], [1, 2]], ["R", "G", "B"], lambda q: q),
    "GBRG": ([[1, 2], [0, 1]], ["R", "G", "B"], lambda q: q),
    "RCCC": ([[0, 1], [1, 1]], ["R", "C"], lambda q: np.column_stack([q[:, 0], q.sum(1)])),
    "RCCB": ([[0, 1], [1, 2]], ["R", "C", "B"], lambda q: np.column_stack([q[:, 0], q.sum(1), q[:, 2]])),
    "RGBW": ([[0, 1], [3, 2]], ["R", "G", "B", "W"], lambda q: np.column_stack([q, q.sum(1)])),
    "MONO": ([[0, 0], [0, 0]], ["M"], lambda q: q.sum(1, keepdims=True)),
}


@settings(max_examples=40, deadline=None)
@given(pattern=st.sampled_from(list(PATTERNS)), h=st.integers(2, 12), w=st.integers(2, 12),
       seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([0.0, 1e-3, 0.5, 1.0, 4.0]),
       correction=st.sampled_from(["none", "gray_world", "white_world", "manual"]),
       demosaic=st.sampled_from(["bilinear", "malvar2004"]), normalize=st.sampled_from(["swing", "max"]))
def test_any_input_gives_finite_bounded_outputs(pattern, h, w, seed, scale, correction, demosaic, normalize):
    tile, names, qe_fn = PATTERNS[pattern]
    qe = qe_fn(camera_like_qe())
    img = np.random.default_rng(seed).random((h, w, len(names))) * scale    # > 1 saturates
    si = sensor_image(np.clip(img, 0, 1), tile, names, qe, pattern=pattern, max_dn=1023.0)
    res = sensor_image_to_srgb(si, ISPParams(illuminant_correction=correction, demosaic=demosaic, normalize=normalize,
                                    manual_gains=(0.8, 1.0, 1.3)))
    _check_outputs(res, (h, w), len(names))
    if res.xyz is not None:
        assert np.all(np.isfinite(res.xyz))


@pytest.mark.parametrize("pattern,expect_order", [("RGGB", [0, 1, 2]), ("RCCC", [0, 1, 1]), ("RGBW", [0, 1, 2]),
                                                  ("MONO", [0, 0, 0])])
def test_representations_as_uint8(pattern, expect_order):
    from workbench.isp import REPRESENTATIONS, representation_to_uint8
    tile, names, qe_fn = PATTERNS[pattern]
    img = np.random.default_rng(5).random((6, 8, len(names)))
    res = sensor_image_to_srgb(sensor_image(img, tile, names, qe_fn(camera_like_qe()), pattern=pattern))
    out = {r: representation_to_uint8(res, r) for r in REPRESENTATIONS}
    for arr in out.values():
        assert arr.shape == (6, 8, 3) and arr.dtype == np.uint8
    np.testing.assert_array_equal(out["raw"][..., 1], np.rint(res.raw * 255))
    np.testing.assert_array_equal(out["linear"], np.rint(res.linear[..., expect_order] * 255))
    np.testing.assert_array_equal(out["srgb"], np.rint(res.srgb * 255))
    with pytest.raises(ValueError, match="allowed"):
        representation_to_uint8(res, "xyz")
