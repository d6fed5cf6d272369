"""Colour error of a rendered Macbeth chart: ΔE2000 of each patch after the ISP (colour-science).

macbeth_delta_e: the rendered patch means (sRGB, the ISP's output) become CIE XYZ (IEC 61966-2-1)
and CIELAB under D65; the reference is the chart's reflectance under D65. Exposure is taken out
first, as a colour-checker measurement does: the rendered XYZ is scaled so that neutral 5 (patch
21, about 19 % reflectance, never clipped at sane exposures) has the reference's luminance.

held_out_delta_e: the same ΔE2000, but of the ISP's XYZ (colour matrix × white balance, before the
sRGB output's gamut clipping) of flat-fielded patch means, each patch once through the matrix fitted
to all 24 ("fitted (training) patches": the chart the matrix was fitted on) and once through the
matrix fitted to the other 23 (leave-one-out: a colour the fit never saw, so an error that
generalises).
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
    from scipy.ndimage import find_objects
    image = np.asarray(image)
    if image.shape[:2] != layout.shape:
        raise InvalidValueError(f"patch means: image {image.shape[:2]} and layout {layout.shape} differ in size")
    boxes = find_objects(np.asarray(layout) + 1, max_label=24)            # patch k is label k + 1
    out = np.zeros((24, image.shape[2]))
    for k, box in enumerate(boxes):
        if box is None:
            raise InvalidValueError(f"patch means: patch {k} is not in the image (too small a chart)")
        ranges = []
        for sl in box:                      # the pixels within shrink/2 of the box's centre, per axis
            centre, half = 0.5 * (sl.start + sl.stop - 1), 0.5 * shrink * (sl.stop - sl.start)
            idx = np.arange(sl.start, sl.stop)
            keep = idx[np.abs(idx - centre) <= half]
            ranges.append(slice(keep[0], keep[-1] + 1))
        inner = image[ranges[0], ranges[1]]
        out[k] = inner.reshape(-1, image.shape[2]).mean(axis=0, dtype=np.float64)
    return out


def _exposure_matched(xyz: np.ndarray) -> np.ndarray:
    """24×3 XYZ scaled so neutral 5 has Y = 1 (exposure taken out, module docstring)."""
    if xyz[NEUTRAL_5, 1] <= 0:
        raise InvalidValueError("ΔE: neutral 5 renders black; expose the chart")
    return xyz / xyz[NEUTRAL_5, 1]


def _scored(xyz: np.ndarray, ref: np.ndarray) -> dict:
    """ΔE2000 of 24 XYZ patch colours (neutral 5 at Y = 1: exposure matched) against the reference Lab."""
    import colour
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    lab = colour.XYZ_to_Lab(xyz * colour.Lab_to_XYZ(ref[NEUTRAL_5], white)[1], white)
    de = delta_e_2000(lab, ref)
    return {"patches": de.tolist(), "mean": float(de.mean()), "max": float(de.max()),
            "worst": PATCH_NAMES[int(de.argmax())], "lab": lab.tolist()}


def held_out_delta_e(linear_means: np.ndarray, linear: np.ndarray, qe: np.ndarray, wavelengths_nm: np.ndarray,
                     isp) -> dict:
    """ΔE2000 of the fitted and of the held-out (leave-one-out) patches (module docstring).

    linear_means: 24×K flat-fielded patch means of the demosaiced sensor channels; linear: the
    ISP's H×W×K image (its white balance statistic is recomputed with each matrix, as the ISP
    would); qe, wavelengths_nm: the sensor's; isp: the ISPParams (a fitted colour_transform).
    Returns {'fitted': …, 'held_out': …}, each {'patches', 'mean', 'max', 'worst', 'lab'}."""
    from workbench.isp.color import fit_sensor_to_xyz, srgb_white_xyz
    from workbench.isp.illuminant import illuminant_gains
    from workbench.isp.process import SATURATED_FRACTION

    def xyz_through(leave_out: int | None) -> np.ndarray:
        fit = fit_sensor_to_xyz(qe, wavelengths_nm, isp.max_condition,
                                preserve_white=isp.colour_transform == "macbeth_d65_wp", leave_out=leave_out)
        gains, _ = illuminant_gains(linear, np.asarray(fit.matrix), isp.illuminant_correction, srgb_white_xyz(),
                                    white_world_fraction=isp.white_world_fraction, manual_gains=isp.manual_gains,
                                    saturated=SATURATED_FRACTION)
        return np.asarray(linear_means, np.float64) @ (fit.matrix * gains)

    ref = reference_lab()
    # patch k through the matrix fitted without it, exposure-matched as that matrix renders neutral 5
    held = np.array([_exposure_matched(xyz_through(k))[k] for k in range(24)])
    return {"fitted": _scored(_exposure_matched(xyz_through(None)), ref), "held_out": _scored(held, ref)}


def macbeth_delta_e(srgb: np.ndarray, layout: np.ndarray) -> dict:
    """ΔE2000 per patch of a rendered chart (module docstring): {'patches': 24 values, 'mean',
    'max', 'worst': patch name, 'lab': 24×3 rendered CIELAB, 'reference_lab'}."""
    import colour
    ref = reference_lab()
    out = _scored(_exposure_matched(colour.sRGB_to_XYZ(np.clip(patch_means(srgb, layout), 0.0, 1.0))), ref)
    return {**out, "reference_lab": ref.tolist()}
