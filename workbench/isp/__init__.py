"""Image-signal processor: SensorImage → raw / linear / sRGB (demosaic, colour, white balance, γ)."""
from workbench.isp.color import (
    ColourFit,
    ColourFitError,
    fit_sensor_to_xyz,
    macbeth_responses,
    srgb_encode,
    srgb_white_xyz,
    xyz_to_linear_srgb_matrix,
    xyz_to_srgb_linear,
)
from workbench.isp.demosaic import DEMOSAIC_METHODS, bayer_pattern, demosaic, demosaic_bilinear
from workbench.isp.illuminant import ILLUMINANT_CORRECTIONS, illuminant_gains
from workbench.isp.params import ISPParams
from workbench.isp.process import (
    BLACK_LEVEL_KEY,
    ISPResult,
    REPRESENTATIONS,
    linear_to_xyz,
    raw_to_linear,
    representation_to_uint8,
    sensor_image_to_srgb,
    xyz_to_srgb,
)

__all__ = [
    "BLACK_LEVEL_KEY", "ColourFit", "ColourFitError", "DEMOSAIC_METHODS", "ILLUMINANT_CORRECTIONS",
    "ISPParams", "ISPResult", "REPRESENTATIONS", "bayer_pattern", "demosaic", "demosaic_bilinear",
    "fit_sensor_to_xyz", "illuminant_gains", "linear_to_xyz", "macbeth_responses",
    "raw_to_linear", "representation_to_uint8", "sensor_image_to_srgb", "srgb_encode", "srgb_white_xyz",
    "xyz_to_linear_srgb_matrix", "xyz_to_srgb", "xyz_to_srgb_linear",
]
