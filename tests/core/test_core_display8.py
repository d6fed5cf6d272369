"""8-bit display copies: the mapping a viewer applies at fixed levels ((x − lo)·255/(hi − lo) in
float32, clipped to [0, 255], truncated), checked against numpy doing the same arithmetic; NaN and
±Inf land on the ends; the copy keeps the image's shape."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.display8 import Display8, display_u8


def numpy_display(image, lo, hi):
    v = (image.astype(np.float32) - np.float32(lo)) * np.float32(255.0 / (hi - lo))
    return np.clip(np.nan_to_num(v, nan=0.0), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("shape, levels", [((48, 64, 3), (0.0, 1.0)), ((48, 64), (0.0, 1023.0)),
                                           ((5, 7, 3), (-0.25, 0.75)), ((1, 1), (0.0, 4095.0))])
def test_display_copy_matches_the_float32_mapping_pixel_for_pixel(shape, levels):
    rng = np.random.default_rng(3)
    lo, hi = levels
    image = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), size=shape).astype(np.float32)
    image.flat[::11] = np.float32(lo + (hi - lo) * 0.5)          # exact level values too
    image.flat[0] = np.float32(hi)
    out = display_u8(image, levels)
    assert out.dtype == np.uint8 and out.shape == image.shape
    assert np.array_equal(out, numpy_display(image, lo, hi))
    assert out.flat[0] == 255


def test_non_finite_values_and_integer_images_and_equal_levels():
    image = np.array([[np.nan, np.inf, -np.inf, 0.5]], np.float32)
    assert display_u8(image, (0.0, 1.0)).tolist() == [[0, 255, 0, 127]]
    dn = np.array([[0, 511, 1023, 2000]], np.uint16)
    assert np.array_equal(display_u8(dn, (0.0, 1023.0)), numpy_display(dn, 0.0, 1023.0))
    assert display_u8(np.array([0.2, 1.5], np.float32), (1.0, 1.0)).tolist() == [0, 127]   # span taken as 1
    with pytest.raises(TypeError):
        display_u8(np.array(["a"]), (0.0, 1.0))


def test_display8_keeps_its_source_and_levels():
    rgb = np.full((2, 3, 3), 0.5, np.float32)
    d = Display8.of(rgb, (0, 1))
    assert d.source is rgb and d.levels == (0.0, 1.0) and d.u8.shape == (2, 3, 3) and int(d.u8[0, 0, 0]) == 127
