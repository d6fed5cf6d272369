"""Parameters of the image-signal processor (one section of the project file / one GUI form)."""
from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator

from workbench.errors import InvalidValueError
from workbench.params import Params


class ISPParams(Params):
    """How a sensor mosaic becomes raw / linear / sRGB images (anchor: ISETCam ipCompute).

    demosaic: a name in `DEMOSAIC_METHODS` ('bilinear', 'malvar2004', 'menon2007'); the latter
        two are Bayer-only and fall back to bilinear (with a note) on other CFAs.
    illuminant_correction: applied in the internal colour space (XYZ, or the sensor channels when
        colour_transform is 'none'). 'gray_world' scales the channels so the image mean has the
        chromaticity of the output white (sRGB's D65 white, i.e. R = G = B); 'gray_pixels' does it
        with the pixels that are nearly grey once corrected (iterated from gray world; robust to a
        coloured scene mean, such as a Macbeth chart's); 'white_world' does the same with the mean over the bright
        pixels (≥ white_world_fraction × max of the brightest channel); 'manual' multiplies the
        internal channels (X, Y, Z or R, G, B) by manual_gains; 'none' leaves them. Y (or the middle channel) is kept, so
        exposure is not changed by the correction. Default 'gray_pixels': plain gray world (DESIGN.md
        §4 and the paper's Fig-6 script; ISETCam's ipCreate default, used for the paper's dataset,
        is 'none') tints the greys of a scene whose mean is coloured, as a camera's would not.
    colour_transform: 'macbeth_d65_wp' (default) fits a sensor→XYZ matrix on the 24 Macbeth
        patches under D65 by least squares under the constraint that the D65 white stays white,
        so greys stay grey; 'macbeth_d65_lsq' is the unconstrained fit (ISETCam's 'MCC
        optimized'; its greys drift by a few per cent); 'none' shows the sensor's R, G, B channels
        as linear sRGB.
        The white balance statistics ('gray_world', 'white_world') leave out saturated pixels
        (a sensor channel ≥ SATURATED_FRACTION of full scale), whose colour is not the scene's.
    highlights: 'neutral' (default) turns pixels whose sensor channels saturate towards the
        neutral white of the output (how a camera renders blown highlights; the sensor clipped
        each channel at its own level, so the clipped colour means nothing); 'clip' keeps the
        colour the matrix gives the clipped channels (ISETCam; a clipped white turns pink).
    max_condition: the largest acceptable condition number of the (column-normalised) Macbeth
        response matrix; above it the fit is ridge-regularised and a note says so.
    normalize: how the rendered image is scaled before clipping and sRGB encoding.
        'swing' (default): fixed scale — a D65 perfect white whose brightest sensor channel fills
        the swing (raw = 1) becomes Y = 1, sRGB ≈ (1, 1, 1) (exact up to the fit residual). Exposure differences (EV bias) stay
        visible, as a camera with fixed rendering would show them.
        'max' (ISETCam's displayRender): each image is divided by its own maximum, which
        partly cancels exposure differences.
    """

    demosaic: str = Field("bilinear", description="demosaicing method (DEMOSAIC_METHODS)")
    illuminant_correction: Literal["none", "gray_world", "gray_pixels", "white_world", "manual"] = Field(
        "gray_pixels", description="white balance in the internal colour space")
    manual_gains: tuple[float, float, float] = Field(
        (1.0, 1.0, 1.0), description="gains of the internal channels for illuminant_correction 'manual'")
    white_world_fraction: float = Field(0.7, gt=0.0, lt=1.0,
                                        description="white world: pixels ≥ this × max of the brightest channel")
    colour_transform: Literal["macbeth_d65_wp", "macbeth_d65_lsq", "none"] = Field(
        "macbeth_d65_wp", description="sensor → XYZ matrix fitted on the Macbeth chart under D65 keeping white "
                                      "white (wp), unconstrained (lsq), or none")
    highlights: Literal["neutral", "clip"] = Field(
        "neutral", description="saturated pixels: towards neutral white (a camera's rendering) or as clipped")
    max_condition: float = Field(1.0e4, ge=10.0, le=1.0e12,
                                 description="condition number above which the colour fit is regularised")
    normalize: Literal["swing", "max"] = Field(
        "swing", description="'swing': fixed scale (keeps EV bias); 'max': per-image maximum (ISETCam)")

    @field_validator("demosaic")
    @classmethod
    def _known_demosaic(cls, value: str) -> str:
        from workbench.isp.demosaic import DEMOSAIC_METHODS
        return DEMOSAIC_METHODS.check(value.strip().lower())

    @field_validator("manual_gains")
    @classmethod
    def _positive_gains(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if not all(0.0 < g <= 100.0 and g == g for g in value):
            raise InvalidValueError(f"manual_gains must be three numbers in (0, 100], got {value}")
        return value
