"""Demosaicing: constant/smooth recovery for every Bayer phase, agreement with colour-demosaicing."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import colour_demosaicing
from isp_synthetic import BAYER_TILES, mosaic
from workbench.compute import pixel_threads
from workbench.compute.local import THREAD_BUDGET_ENV
from workbench.isp.demosaic import (
    DEMOSAIC_METHODS, bayer_pattern, bilinear_2x2_tile, bilinear_tent_convolution, demosaic,
    demosaic_bilinear,
)

RGB = ["R", "G", "B"]


def smooth_image(h=24, w=32, k=3):
    """An affine ramp per channel (bilinear interpolation reproduces it exactly in the interior)."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    return np.stack([0.1 + 0.02 * x + 0.01 * y * (i + 1) / k for i in range(k)], axis=2) / 2.0


@pytest.mark.parametrize("pattern", list(BAYER_TILES))
def test_bayer_pattern_mapping(pattern):
    assert bayer_pattern(np.array(BAYER_TILES[pattern]), RGB) == pattern
    # channel order of the sensor does not matter: the tile indexes into channel_names
    names = ["B", "G", "R"]
    tile = np.array(BAYER_TILES[pattern])
    swapped = np.choose(tile, [2, 1, 0])
    assert bayer_pattern(swapped, names) == pattern


@pytest.mark.parametrize("method", list(DEMOSAIC_METHODS))
@pytest.mark.parametrize("pattern", list(BAYER_TILES))
def test_constant_image_recovered(method, pattern):
    truth = np.broadcast_to(np.array([0.2, 0.5, 0.8], dtype=np.float32), (20, 24, 3))
    planes, notes = demosaic(mosaic(truth, BAYER_TILES[pattern]), BAYER_TILES[pattern], RGB, method)
    assert planes.dtype == np.float32 and planes.shape == truth.shape and notes == []
    interior = (slice(3, -3), slice(3, -3))
    np.testing.assert_allclose(planes[interior], truth[interior], atol=1e-5)
    if method == "bilinear":   # mirror borders keep the CFA phase: exact everywhere
        np.testing.assert_allclose(planes, truth, atol=1e-6)


@pytest.mark.parametrize("pattern", list(BAYER_TILES))
def test_smooth_image_recovered_bilinear(pattern):
    truth = smooth_image()
    planes, _ = demosaic_bilinear(mosaic(truth, BAYER_TILES[pattern]), BAYER_TILES[pattern], 3)
    np.testing.assert_allclose(planes[1:-1, 1:-1], truth[1:-1, 1:-1], atol=1e-5)


@pytest.mark.parametrize("pattern", list(BAYER_TILES))
def test_fast_bilinear_equals_colour_demosaicing(pattern):
    rng = np.random.default_rng(7)
    cfa = rng.random((48, 64)).astype(np.float32)
    ours, _ = demosaic_bilinear(cfa, BAYER_TILES[pattern], 3)
    ref = colour_demosaicing.demosaicing_CFA_Bayer_bilinear(cfa, pattern)
    # colour-demosaicing pads with scipy 'reflect' (edge repeated), which breaks the CFA phase on
    # the outermost pixels; we mirror without repeating. The interior must agree.
    np.testing.assert_allclose(ours[1:-1, 1:-1], ref[1:-1, 1:-1], atol=1e-5)


@settings(max_examples=25, deadline=None)
@given(h=st.integers(3, 17), w=st.integers(3, 17), pattern=st.sampled_from(list(BAYER_TILES)),
       seed=st.integers(0, 2**31 - 1))
def test_fast_bilinear_property(h, w, pattern, seed):
    cfa = np.random.default_rng(seed).random((h, w)).astype(np.float32)
    ours, _ = demosaic_bilinear(cfa, BAYER_TILES[pattern], 3)
    ref = colour_demosaicing.demosaicing_CFA_Bayer_bilinear(cfa, pattern)
    np.testing.assert_allclose(ours[1:-1, 1:-1], ref[1:-1, 1:-1], atol=1e-5)
    # measured samples are kept and results stay within the data range
    np.testing.assert_array_equal(mosaic(ours, BAYER_TILES[pattern]), cfa)
    assert ours.min() >= cfa.min() - 1e-6 and ours.max() <= cfa.max() + 1e-6


@pytest.mark.parametrize("tile,names", [
    ([[0, 1], [1, 1]], ["R", "C"]),                     # RCCC
    ([[0, 1], [1, 2]], ["R", "C", "B"]),                # RCCB
    ([[0, 1], [3, 2]], ["R", "G", "B", "W"]),           # RGBW
    ([[0]], ["M"]),                                     # MONO
    ([[0, 0, 1, 1], [0, 0, 1, 1], [1, 1, 2, 2], [1, 1, 2, 2]], RGB),   # quad Bayer
])
def test_other_cfas_constant_and_smooth(tile, names):
    k = len(names)
    const = np.broadcast_to(np.linspace(0.2, 0.9, k).astype(np.float32), (16, 20, k))
    planes, _ = demosaic(mosaic(const, tile), tile, names)
    np.testing.assert_allclose(planes, const, atol=1e-6)
    smooth = smooth_image(16, 20, k)
    planes, _ = demosaic(mosaic(smooth, tile), tile, names)
    r = len(tile)
    np.testing.assert_allclose(planes[r:-r, r:-r], smooth[r:-r, r:-r], atol=1e-5)


def test_non_bayer_with_bayer_only_method_falls_back_with_note():
    tile = [[0, 1], [1, 1]]
    planes, notes = demosaic(np.full((8, 8), 0.5, np.float32), tile, ["R", "C"], "menon2007")
    assert planes.shape == (8, 8, 2) and np.allclose(planes, 0.5)
    assert notes and "bilinear" in notes[0]


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="unknown"):
        demosaic(np.zeros((4, 4)), BAYER_TILES["RGGB"], RGB, "nearest")
    with pytest.raises(ValueError, match="channel indices"):
        demosaic(np.zeros((4, 4)), [[0, 1], [1, 0]], RGB)
    with pytest.raises(ValueError, match="H×W"):
        demosaic(np.zeros((4, 4, 3)), BAYER_TILES["RGGB"], RGB)


@settings(max_examples=30, deadline=None)
@given(h=st.integers(2, 15), w=st.integers(2, 15), seed=st.integers(0, 2**31 - 1),
       tile=st.sampled_from([[[0, 1], [1, 2]], [[0, 1], [1, 1]], [[0, 1], [3, 2]], [[0, 0], [1, 2]],
                             [[2, 0], [1, 1]]]))
def test_compiled_2x2_route_equals_tent_convolution(h, w, seed, tile):
    """The compiled 2×2 route and the any-tile convolution are the same algorithm, borders included."""
    tile = np.array(tile)
    k = int(tile.max()) + 1
    cfa = np.random.default_rng(seed).random((h, w)).astype(np.float32)
    np.testing.assert_allclose(bilinear_2x2_tile(cfa, tile, k), bilinear_tent_convolution(cfa, tile, k), atol=2e-6)


def test_a_large_frame_in_threads_equals_tent_convolution(monkeypatch):
    """Row blocks in threads join up: a frame above the threading threshold, odd-sized."""
    monkeypatch.setenv(THREAD_BUDGET_ENV, "2")
    tile = np.array(BAYER_TILES["GRBG"])
    cfa = np.random.default_rng(2).random((301, 257)).astype(np.float32)
    assert cfa.size >= pixel_threads.PARALLEL_MIN_PIXELS
    np.testing.assert_allclose(bilinear_2x2_tile(cfa, tile, 3), bilinear_tent_convolution(cfa, tile, 3), atol=2e-6)


@pytest.mark.parametrize("pattern", ["RGGB", "GRBG", "BGGR", "GBRG"])
@pytest.mark.parametrize("h, w", [(3, 3), (7, 9), (240, 320)])
def test_compiled_malvar_equals_colour_demosaicing_on_a_mirrored_mosaic(pattern, h, w):
    """Oracle: colour-demosaicing's Malvar (2004) on the mosaic mirrored by 2 pixels (numpy 'reflect',
    which keeps the CFA phase) sees, inside the crop, exactly the neighbourhoods our kernel mirrors
    into; the clip to the data range is the wrapper's. 240×320 runs in threads."""
    import colour_demosaicing
    names = sorted(set(pattern), key=pattern.index)            # channel order as the pattern first lists it
    tile = np.array([[names.index(c) for c in pattern[:2]], [names.index(c) for c in pattern[2:]]])
    cfa = np.random.default_rng(h * w).random((h, w)).astype(np.float32)
    ours, notes = demosaic(cfa, tile, names, "malvar2004")
    ref = colour_demosaicing.demosaicing_CFA_Bayer_Malvar2004(np.pad(cfa.astype(np.float64), 2, mode="reflect"),
                                                              pattern)[2:-2, 2:-2]
    ref = np.clip(ref[..., ["RGB".index(n) for n in names]], cfa.min(), cfa.max())
    assert notes == [] and ours.dtype == np.float32
    np.testing.assert_allclose(ours, ref, atol=5e-7)
