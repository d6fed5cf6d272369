"""Sensor parameters (DESIGN.md §4; ISETCam's pixel and sensor structures) and presets.

Units are in the field names. Conventions that differ from ISETCam are stated on the field:
analog gain multiplies (ISETCam divides), an exposure of 0 s is a zero exposure (ISETCam turns
auto-exposure on), and `exposure_s=None` asks for auto-exposure.
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field, create_model, field_validator, model_validator

from workbench.errors import InvalidValueError
from workbench.params import Params

MAX_PIXELS = 2 ** 25
"""Largest sensor simulated in memory (33.5 Mpx, e.g. 8192×4096): each full-frame stage keeps a
few float32 copies, and the optical image upstream is H×W×Nλ."""
MIN_FULL_WELL_E = 1.0     # electrons a pixel holds at the least (below, every signal is under one electron)

CFA_PATTERNS = ("RGGB", "GRBG", "GBRG", "BGGR", "RCCC", "RCCB", "RGBW", "MONO")

CfaPattern = Literal["RGGB", "GRBG", "GBRG", "BGGR", "RCCC", "RCCB", "RGBW", "MONO"]
AutoExposureMethod = Literal["mean", "brightest", "percentile", "cfa"]


class SensorParams(Params):
    """Everything that defines a simulated image sensor: the pixel response (the fields of
    PixelResponseParams, what the noise-free signal rate reads) and exposure, noise and read-out.

    noise_flag (ISETCam's `noiseFlag`):
      -1  ideal: mean electrons only; no noise, no analog gain/offset, no clipping of volts
          (DN are still quantised and limited to the code range);
       0  no noise; analog gain/offset, clipping to the swing and quantisation;
       1  as 0 plus photon shot noise (true Poisson);
       2  as 1 plus dark current, read noise, PRNU, DSNU and column FPN (the default).

    pixel_aperture: the light-sensitive area a pixel integrates over. Automotive CMOS sensors, like
    camera sensors generally, put an on-chip microlens on every pixel, which converges the light
    of the whole pixel onto the photodiode and raises the effective fill factor to nearly 100 %
    (S. Battiato et al. (eds.), Image Processing for Embedded Devices, Bentham 2010, pp. 12 and
    29); hence the default 'microlens' (aperture = the full pitch). 'photodiode' models a pixel
    without one: a centred square photodiode of √fill_factor × pitch.
    fill_factor always scales the collected signal (A·FF·QE); the aperture model sets the MTF.
    """

    rows: int = Field(480, ge=1, le=65536, description="pixel rows (image height); sensor geometry and signal stage")
    cols: int = Field(640, ge=1, le=65536, description="pixel columns (image width); sensor geometry and signal stage")
    pixel_pitch_um: float = Field(3.0, ge=0.3, le=100.0,
                                  description="pixel centre spacing (µm); sets the sensor width, so the field of "
                                              "view and the optical-image sample spacing (pitch / oversample)")
    fill_factor: float = Field(0.75, gt=0.0, le=1.0,
                               description="photosensitive fraction of the pixel area (0–1); signal stage")
    pixel_aperture: Literal["microlens", "photodiode"] = Field(
        "microlens", description="the area each pixel integrates light over, so its MTF: 'microlens' the full "
                                 "pitch (a microlens focuses the pixel's light onto the photodiode, MTF "
                                 "sinc(f·pitch)); 'photodiode' a bare centred square of √fill_factor × pitch "
                                 "(MTF sinc(f·√FF·pitch)); signal stage, metrics")
    conversion_gain_uV_per_e: float = Field(100.0, ge=0.1, le=1000.0,
                                            description="conversion gain (µV per electron, 0.1–1,000: real pixels "
                                                        "have 10–500); sensor stage")
    voltage_swing_V: float = Field(1.0, gt=0.0, le=10.0, description="pixel output range (V); sensor stage")
    dark_voltage_V_per_s: float = Field(1e-3, ge=0.0, le=10.0,
                                        description="dark-current voltage rate (V/s); sensor stage, noise_flag 2")
    read_noise_V: float = Field(1e-3, ge=0.0, le=1.0, description="read noise σ (V); sensor stage, noise_flag 2")
    dsnu_sigma_V: float = Field(0.0, ge=0.0, le=1.0,
                                description="dark-signal non-uniformity σ (V); sensor stage, noise_flag 2")
    prnu_sigma_pct: float = Field(0.0, ge=0.0, le=50.0,
                                  description="photo-response non-uniformity σ (%); sensor stage, noise_flag 2")
    column_fpn_offset_sigma_V: float = Field(0.0, ge=0.0, le=1.0,
                                             description="column offset σ (V); sensor stage, noise_flag 2")
    column_fpn_gain_sigma_pct: float = Field(0.0, ge=0.0, le=50.0,
                                             description="column gain σ (%); sensor stage, noise_flag 2")
    analog_gain: float = Field(1.0, gt=0.0, le=1000.0,
                               description="volts out = analog_gain × volts + analog_offset_V (unitless; "
                                           "ISETCam's gain divides); sensor stage")
    analog_offset_V: float = Field(0.0, ge=-10.0, le=10.0,
                                   description="black-level offset added after the gain (V); sensor stage")
    bit_depth: int = Field(8, ge=0, le=24, description="ADC bits; 0 = analog read-out in volts; sensor stage")
    cfa_pattern: CfaPattern = Field("GRBG", description="2×2 colour-filter tile read row by row; signal stage, ISP")
    filter_file: str | None = Field("sensors/bayer_dye_filters.csv",
                                    description="colour-filter transmittance CSV under resources/ (columns named "
                                                "R,G,B,C,W); None = no colour filters (MONO only); signal stage")
    photodiode_qe_file: str | None = Field("sensors/silicon_photodiode_qe.csv",
                                           description="photodiode QE CSV under resources/; None = QE 1 "
                                                       "(ISETCam's default pixel); signal stage")
    ir_cut_file: str | None = Field("sensors/ir_cut_650.csv",
                                    description="IR-cut filter transmittance CSV under resources/; None = no IR "
                                                "cut; signal stage")
    regrid_method: Literal["area", "isetcam"] = Field(
        "area", description="optical image → pixel grid when their spacings differ: 'area' averages over "
                            "each pixel (flux conserving); 'isetcam' = Gaussian pre-blur + bilinear "
                            "(regridOI2ISA); signal stage")
    exposure_s: float | list[list[float]] | None = Field(
        None, description="exposure (s): a number, a per-CFA-position tile (rows of the CFA tile), "
                          "or None for auto-exposure; sensor stage")
    auto_exposure_method: AutoExposureMethod = Field(
        "mean", description="auto-exposure method (AUTO_EXPOSURE_METHODS) when exposure_s is None; sensor stage")
    auto_exposure_level: float = Field(0.4, gt=0.0, le=1.0,
                                       description="auto-exposure target as a fraction of the swing (0–1; the "
                                                   "percentile fraction for 'percentile'); the paper's experiment "
                                                   "uses mean 0.4; sensor stage")
    ev_bias: float = Field(0.0, ge=-16.0, le=16.0,
                           description="exposure bias (EV): t = t0 · 2^ev_bias, t0 = exposure_s or the "
                                       "auto-exposure; sensor stage")
    max_exposure_s: float = Field(10.0, gt=0.0, le=3600.0,
                                  description="longest exposure auto-exposure may pick (s); sensor stage")
    noise_flag: Literal[-1, 0, 1, 2] = Field(
        2, description="-1 ideal, 0 no noise, 1 shot noise, 2 all noise (see the class doc); sensor stage")
    seed: int = Field(0, ge=0, le=2 ** 63 - 1,
                      description="seed of the fixed patterns and of the temporal noise; sensor stage")

    @field_validator("noise_flag", mode="before")
    @classmethod
    def _noise_flag_whole_number(cls, v):
        """A Literal of ints takes true as 1 and 2.0 as 2 (they compare equal): refused, as every number
        field refuses bools and strings."""
        if isinstance(v, bool) or not isinstance(v, int):
            raise InvalidValueError(f"noise_flag must be one of -1, 0, 1, 2 (a whole number), got {v!r}")
        return v

    @field_validator("exposure_s")
    @classmethod
    def _exposure_not_negative(cls, v):
        if v is None:
            return v
        values = [v] if isinstance(v, (int, float)) else [x for row in v for x in row]
        bad = [x for x in values if not (x >= 0.0 and x <= 3600.0)]
        if bad:
            raise InvalidValueError(f"exposure must lie in 0–3600 s, got {bad[0]}")
        if not isinstance(v, (int, float)) and (not v or len({len(r) for r in v}) != 1 or not v[0]):
            raise InvalidValueError("a per-CFA exposure must be a non-empty rectangular list of rows")
        return v

    @field_validator("filter_file", "photodiode_qe_file", "ir_cut_file")
    @classmethod
    def _valid_spectrum_file(cls, v):
        """Confined to resources/, readable, finite, in [0, 1], wavelengths strictly increasing."""
        from workbench.spectrum_csv import check_spectrum_file
        return v if v is None else check_spectrum_file(v)

    @model_validator(mode="after")
    def _pixels_and_filters(self):
        n = self.rows * self.cols
        if n > MAX_PIXELS:
            raise InvalidValueError(
                f"sensor of rows×cols = {self.rows}×{self.cols} = {n:,} pixels exceeds the simulation limit "
                f"of {MAX_PIXELS:,} pixels; reduce rows/cols (simulate a crop or a binned sensor with a "
                f"larger pixel_pitch_um)")
        from workbench.sensor.cfa import cfa_layout
        _, names = cfa_layout(self.cfa_pattern)
        needed = [c for c in names if c != "M"]
        if needed:
            if self.filter_file is None:
                raise InvalidValueError(f"cfa_pattern {self.cfa_pattern} needs colour filters {needed}; filter_file is None")
            from workbench.spectrum_csv import read_spectrum
            have = read_spectrum(self.filter_file).names
            missing = [c for c in needed if c not in have]
            if missing:
                raise InvalidValueError(f"filter_file '{self.filter_file}' has no curve {', '.join(missing)}, "
                                 f"needed by cfa_pattern {self.cfa_pattern}")
        return self

    @model_validator(mode="after")
    def _consistent(self):
        if abs(self.analog_offset_V) >= self.voltage_swing_V:
            raise InvalidValueError(f"analog_offset_V = {self.analog_offset_V} V must be smaller in magnitude than "
                             f"voltage_swing_V = {self.voltage_swing_V} V")
        if not self.full_well_e >= MIN_FULL_WELL_E:
            raise InvalidValueError(f"voltage_swing_V / conversion gain = {self.full_well_e:.3g} e⁻ of full well: a "
                                    f"pixel must hold at least {MIN_FULL_WELL_E:g} electron; raise voltage_swing_V "
                                    "or lower conversion_gain_uV_per_e")
        from workbench.sensor.cfa import cfa_layout
        tile, _ = cfa_layout(self.cfa_pattern)
        if isinstance(self.exposure_s, list):
            shape = (len(self.exposure_s), len(self.exposure_s[0]))
            if shape != tile.shape:
                raise InvalidValueError(f"exposure_s tile has shape {shape}, the {self.cfa_pattern} CFA tile is {tile.shape}")
        return self

    # Derived quantities -------------------------------------------------------------------
    @property
    def pixel_response(self) -> "PixelResponseParams":
        """Only the pixel-response fields: the signal stage's input (its cache key)."""
        return PixelResponseParams.model_validate(self.model_dump(include=set(PIXEL_RESPONSE_FIELDS)))

    @property
    def pixel_area_m2(self) -> float:
        return (self.pixel_pitch_um * 1e-6) ** 2

    @property
    def sensor_size_m(self) -> tuple[float, float]:
        """(height, width) of the pixel array (m)."""
        p = self.pixel_pitch_um * 1e-6
        return self.rows * p, self.cols * p

    @property
    def aperture_width_px(self) -> float:
        """Side of the square the pixel integrates light over, in pixel pitches (pixel_aperture)."""
        return 1.0 if self.pixel_aperture == "microlens" else self.fill_factor ** 0.5

    @property
    def conversion_gain_V_per_e(self) -> float:
        return self.conversion_gain_uV_per_e * 1e-6

    @property
    def full_well_e(self) -> float:
        """Electrons that fill the voltage swing (swing / conversion gain)."""
        return self.voltage_swing_V / self.conversion_gain_V_per_e

    @property
    def dark_current_e_per_s(self) -> float:
        return self.dark_voltage_V_per_s / self.conversion_gain_V_per_e

    @property
    def read_noise_e(self) -> float:
        return self.read_noise_V / self.conversion_gain_V_per_e

    @property
    def lsb_V(self) -> float:
        """Volts per code (swing / 2^bits); 1.0 for an analog read-out, whose DN are its volts (unquantised)."""
        return self.voltage_swing_V / 2 ** self.bit_depth if self.bit_depth else 1.0

    @property
    def max_dn(self) -> float:
        """Largest output code (2^bits − 1), or the swing (V) for an analog read-out."""
        return float(2 ** self.bit_depth - 1) if self.bit_depth else self.voltage_swing_V


PIXEL_RESPONSE_FIELDS = ("rows", "cols", "pixel_pitch_um", "fill_factor", "pixel_aperture", "cfa_pattern",
                         "filter_file", "photodiode_qe_file", "ir_cut_file", "regrid_method")


class _PixelResponse(Params):
    """The pixel array and its spectral response: all the noise-free signal rate
    (sensor.irradiance_to_signal_rate) reads, so it is that stage's input and cache key. Its fields are
    SensorParams' PIXEL_RESPONSE_FIELDS (same types, ranges and descriptions)."""

    @property
    def pixel_response(self) -> "PixelResponseParams":
        return self

    pixel_area_m2 = SensorParams.pixel_area_m2
    sensor_size_m = SensorParams.sensor_size_m
    aperture_width_px = SensorParams.aperture_width_px


PixelResponseParams = create_model(
    "PixelResponseParams", __base__=_PixelResponse, __module__=__name__,
    **{name: (SensorParams.model_fields[name].annotation, SensorParams.model_fields[name])
       for name in PIXEL_RESPONSE_FIELDS})


SENSOR_PRESETS: dict[str, SensorParams] = {
    # The paper's camera (Table 1) on ISETCam's default pixel: 10,000 e⁻ well, 10 e⁻ read noise.
    "paper_table1": SensorParams(),
    # ISETCam sensorCreate(): qqcif 72×88, 2.8 µm, GRBG, analog volts, pd QE 1, brightest AE at 0.95.
    "isetcam_default": SensorParams(rows=72, cols=88, pixel_pitch_um=2.8, bit_depth=0,
                                    photodiode_qe_file=None, auto_exposure_method="brightest",
                                    auto_exposure_level=0.95),
    # ON Semi MT9V024-like automotive RCCC: 6 µm, FF 0.8, 110 µV/e⁻, 2.8 V (25,455 e⁻), no IR cut
    # (QE data to 1100 nm; give the scene NIR bands to use it), 10-bit ADC.
    "auto_rccc": SensorParams(rows=480, cols=752, pixel_pitch_um=6.0, fill_factor=0.8,
                              conversion_gain_uV_per_e=110.0, voltage_swing_V=2.8, bit_depth=10,
                              cfa_pattern="RCCC", ir_cut_file=None),
    # ON Semi AR0132AT-like automotive RGGB: 3.75 µm, 110 µV/e⁻, 2.8 V (25,455 e⁻), 12-bit.
    "auto_rggb": SensorParams(rows=960, cols=1280, pixel_pitch_um=3.75, conversion_gain_uV_per_e=110.0,
                              voltage_swing_V=2.8, bit_depth=12, cfa_pattern="RGGB"),
}
