"""Colour error of a rendered Macbeth chart: ΔE2000 of each patch after the ISP (colour-science).

The rendered patch means (sRGB, the ISP's output) become CIE XYZ (IEC 61966-2-1) and CIELAB under
D65; the reference is the chart's reflectance under D65. Exposure is taken out first, as a
colour-checker measurement does: the rendered XYZ is scaled so that neutral 5 (patch 21, about
19 % reflectance, never clipped at sane exposures) has the reference's luminance.
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError

NEUTRAL_5 = 21
PATCH_NAMES = ("dark skin", "light skin", "blue sky", "foliage", "blue flower", "bluish green", "orange",
               "purplish blue", "moderate red", "purple", "yellow green", "orange yellow", "blue", "green",
               "red", "yellow", "magenta", "cyan", "white 9.5", "neutral 8", "neutral 6.5", "neutral 5",
               "neutral 3.5", "black 2")


def delta_e_2000(lab_a: np.ndarray, lab_b: np.ndarray) -> np.ndarray:
    """ΔE2000 between CIELAB colours (…×3), by colour-science."""
    import colour
    return np.asarray(colour.delta_E(np.asarray(lab_a, np.float64), np.asarray(lab_b, np.float64),
                                     method="CIE 2000"), dtype=np.float64)


def reference_lab() -> np.ndarray:
    """24×3 CIELAB of the Macbeth patches under D65 (white: the perfect diffuser)."""
    import colour

    from workbench.spectra import illuminant_spd, macbeth_reflectances, xyz_cmfs
    wl = np.arange(380.0, 781.0, 5.0)
    d65 = illuminant_spd("D65", wl)
    cmfs = xyz_cmfs(wl)
    xyz = (macbeth_reflectances(wl) * d65) @ cmfs / (d65 @ cmfs[:, 1])
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    return colour.XYZ_to_Lab(xyz, white)


def patch_means(image: np.ndarray, layout: np.ndarray, shrink: float = 0.5) -> np.ndarray:
    """24×C means of each patch's central part (layout: patch index per pixel, −1 between patches;
    shrink: the fraction of each patch's width and height used, away from its edges)."""
    image = np.asarray(image, np.float64)
    if image.shape[:2] != layout.shape:
        raise InvalidValueError(f"patch means: image {image.shape[:2]} and layout {layout.shape} differ in size")
    out = np.zeros((24, image.shape[2]))
    for k in range(24):
        ys, xs = np.nonzero(layout == k)
        if ys.size == 0:
            raise InvalidValueError(f"patch means: patch {k} is not in the image (too small a chart)")
        cy, cx = 0.5 * (ys.min() + ys.max()), 0.5 * (xs.min() + xs.max())
        hy, hx = 0.5 * shrink * (ys.max() - ys.min() + 1), 0.5 * shrink * (xs.max() - xs.min() + 1)
        inner = (np.abs(ys - cy) <= hy) & (np.abs(xs - cx) <= hx)
        out[k] = image[ys[inner], xs[inner]].mean(axis=0)
    return out


def macbeth_delta_e(srgb: np.ndarray, layout: np.ndarray) -> dict:
    """ΔE2000 per patch of a rendered chart (module docstring): {'patches': 24 values, 'mean',
    'max', 'worst': patch name, 'lab': 24×3 rendered CIELAB, 'reference_lab'}."""
    import colour
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    xyz = colour.sRGB_to_XYZ(np.clip(patch_means(srgb, layout), 0.0, 1.0))
    ref = reference_lab()
    ref_y = colour.Lab_to_XYZ(ref[NEUTRAL_5], white)[1]
    if xyz[NEUTRAL_5, 1] <= 0:
        raise InvalidValueError("ΔE: neutral 5 renders black; expose the chart")
    lab = colour.XYZ_to_Lab(xyz * (ref_y / xyz[NEUTRAL_5, 1]), white)
    de = delta_e_2000(lab, ref)
    return {"patches": de.tolist(), "mean": float(de.mean()), "max": float(de.max()),
            "worst": PATCH_NAMES[int(de.argmax())], "lab": lab.tolist(), "reference_lab": ref.tolist()}
