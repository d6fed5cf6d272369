"""Parameters of the spectral render: spectral representation, sampling budget, daylight."""
from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from workbench.errors import InvalidValueError
from workbench.params import Params

class DaylightParams(Params):
    """Sun (directional) + sky, both spectral over 300–1100 nm (NIR included).

    The sun's position comes from `sun_elevation_deg`/`sun_azimuth_deg` (compass azimuth:
    0 = north = +Y, 90 = east = +X), or, when `time_of_day_h` is set, from local solar time,
    latitude and day of year (the angles are then ignored). `turbidity` is the Linke/Preetham
    turbidity (2 = very clear, 3 = clear, 6+ = hazy); it sets the Ångström aerosol coefficient.
    `sun_visible`: composite the solar disc (0.53° wide) onto pinhole renders where camera rays
    reach the sky (render/sun_disc.py); the directional sun lights the scene either way.
    `sky_model` (render/sky.py): 'uniform' (SPCTRAL2 diffuse spread evenly), 'perez' (clear sky
    brightening toward the sun and the horizon, same horizontal irradiance) or 'overcast' (CIE
    overcast sky, no direct sun; `overcast_transmittance` × the clear-sky global irradiance)."""

    sun_elevation_deg: float = Field(45.0, gt=0.0, le=90.0, description="sun elevation above the horizon (deg); "
                                                                        "city render daylight")
    sun_azimuth_deg: float = Field(135.0, ge=0.0, lt=360.0, description="sun compass azimuth, 0 = north = +Y, "
                                                                        "90 = east (deg); city render daylight")
    time_of_day_h: float | None = Field(None, ge=0.0, le=24.0,
                                        description="local solar time (h); when set it places the sun (the angles "
                                                    "are ignored); city render daylight")
    latitude_deg: float = Field(37.4, ge=-90.0, le=90.0, description="latitude for time_of_day_h (deg); city render")
    day_of_year: int = Field(172, ge=1, le=366, description="day of the year for time_of_day_h; city render")
    turbidity: float = Field(3.0, ge=1.0, le=10.0, description="Linke turbidity (2 very clear … 6+ hazy); "
                                                               "city render daylight")
    sun_scale: float = Field(1.0, ge=0.0, le=1e3, description="sun radiance multiplier (unitless); city render")
    sky_scale: float = Field(1.0, ge=0.0, le=1e3, description="sky radiance multiplier (unitless); city render")
    sun_visible: bool = Field(True, description="composite the 0.53° solar disc onto pinhole renders; city render")
    sky_model: Literal["uniform", "perez", "overcast"] = Field(
        "uniform", description="sky radiance distribution: uniform, Perez clear sky or CIE overcast; city render")
    overcast_transmittance: float = Field(0.3, gt=0.0, le=1.0, description="overcast global irradiance as a "
                                                                           "fraction of the clear sky's (0–1)")

    @model_validator(mode="after")
    def _sun_above_horizon(self) -> "DaylightParams":
        """A time of day that puts the sun below the horizon is refused here, not at render time."""
        if self.time_of_day_h is not None:
            from workbench.errors import ParameterError
            from workbench.render.solar import solar_position
            elevation_deg = solar_position(self.time_of_day_h, self.latitude_deg, self.day_of_year)[0]
            if elevation_deg <= 0.5:
                raise ParameterError("time_of_day_h", self.time_of_day_h,
                                     f"puts the sun at {elevation_deg:.1f}° elevation (latitude {self.latitude_deg}°, "
                                     f"day {self.day_of_year}); daylight needs the sun above the horizon (> 0.5°)")
        return self


MIN_SKY_CD_M2 = 1e-6      # below it the glow's spectrum underflows float32 in Mitsuba (1e-40 crashed)


class NightParams(Params):
    """Night lighting (render/lamps.py): the city's street lamps as full-cut-off point sources (uniform
    over the lower hemisphere) of
    `lamp_kind` spectrum and luminous flux `lamp_flux_lm` (None = the kind's rated flux), vehicle
    head-lights (`headlight_kind`, `headlight_cd` peak) and tail-lights (red LED, `taillight_cd`)
    when `vehicle_lights`, and a uniform sky glow of luminance `sky_luminance_cd_m2` (a 3500 K
    blackbody shape; urban skies are ~0.01–0.1 cd/m²). `light_selection`: how next-event estimation
    picks a light — 'view' (by each light's direct illuminance on what the camera sees, plus a
    10 % flux share: the same image with far less noise than flux), 'flux' (by luminous flux
    alone) or 'shading' (render/lamp_set.py: all lamps one emitter that picks a lamp by its
    unshadowed light at each shading point, as a light tree does; the same image again). With
    'view' the noise left at night is fireflies of one-bounce indirect light (render.max_depth 2
    has none): a bounced path lands on a surface lit by a lamp whose per-frame share is small.
    'shading' removes that cause; max_depth 2 instead loses the indirect light: on the render
    bench's view −5 % on lit surfaces (−0.7 % of the frame mean), depth 3 −2.5 %, depth 4 within
    0.2 % of depth 10."""

    lamp_kind: Literal["lps", "hps", "led", "metal_halide"] = Field("hps", description="street-lamp spectrum; "
                                                                                      "night render")
    lamp_flux_lm: float | None = Field(None, ge=1.0, le=1e6, description="luminous flux per lamp (lm, from 1: a candle "
                                                                         "gives 12); None = the kind's rated flux; "
                                                                         "night render")
    vehicle_lights: bool = Field(True, description="head- and tail-lights of moving vehicles on (parked cars "
                                                   "stay dark); night render")
    headlight_kind: Literal["halogen", "led"] = Field("led", description="head-light spectrum; night render")
    headlight_cd: float = Field(20000.0, ge=1.0, le=1e6,
                                description="head-light low beam's hot-spot intensity (cd, 1.5° down, 2° right; "
                                            "SAE J1383 allows ≤ 20,000 at 0.5° down, 1.5° right); night render")
    taillight_cd: float = Field(10.0, ge=0.1, le=1e4, description="tail-light intensity (cd, from 0.1; regulations "
                                                                  "ask ≥ 4); night render")
    sky_luminance_cd_m2: float = Field(0.02, ge=0.0, le=10.0, description="night sky glow luminance (cd/m²; 0 = "
                                                                          f"none, else from {MIN_SKY_CD_M2:g}: "
                                                                          "the darkest natural sky is ~2e-4); "
                                                                          "night render")
    light_selection: Literal["view", "flux", "shading"] = Field(
        "view", description="lights sampled by their light on the view, by flux alone, or by their light at each "
                            "shading point (fewest fireflies); night render")

    @field_validator("sky_luminance_cd_m2")
    @classmethod
    def _sky_off_or_visible(cls, v: float) -> float:
        if 0 < v < MIN_SKY_CD_M2:
            raise InvalidValueError(f"must be 0 (no sky glow) or at least {MIN_SKY_CD_M2:g} cd/m², got {v:g}")
        return v


class FogParams(Params):
    """Fog or haze (render/fog.py): `model` 'koschmieder' (clear-air render fogged per pixel by
    Koschmieder's law with a measured airlight: cheap, the data-set default) or 'volumetric' (a
    homogeneous participating medium rendered by volpath: the reference, ~10³× the cost); meteorological
    visibility `visibility_m` (extinction σ = 3.912 / V, Koschmieder, 2 % contrast), single-
    scattering `albedo` (water droplets ≈ 0.99, urban haze ≈ 0.9), Henyey–Greenstein asymmetry
    `phase_g` (fog droplets scatter forward, ≈ 0.85), in a layer `height_m` deep over the city.
    Droplets ≫ λ, so σ is the same at every wavelength."""

    visibility_m: float = Field(200.0, ge=10.0, le=1e5, description="meteorological visibility (m), from 10 m "
                                "(the densest fog the models are checked for; nearer, the fog model's "
                                "in-scattering underflows) to 100 km; fog medium")
    albedo: float = Field(0.98, ge=0.0, le=1.0, description="single-scattering albedo (0–1); fog medium")
    phase_g: float = Field(0.85, gt=-1.0, lt=1.0, description="Henyey–Greenstein asymmetry (−1…1); fog medium")
    height_m: float = Field(100.0, gt=1.0, le=1e4, description="fog layer depth over the city (m); fog medium")
    model: Literal["koschmieder", "volumetric"] = Field(
        "koschmieder", description="Koschmieder's law per pixel (cheap) or a volumetric medium (reference); fog")


class WorldParams(Params):
    """Scene features beyond geometry, each switchable: `lighting` 'day' (render.daylight) or
    'night' (`night`); `fog` (None = clear air); `glass` 'diffuse' (windows as dark Lambertian
    surfaces, as before) or 'dielectric' (a thin glass pane, n = 1.52: see-through, Fresnel
    reflection of the sky); `materials` 'uniform' (one spectrum per material, as before) or
    'procedural' (asphalt, concrete, brick, stucco, sandstone and grass as texture-weighted blends
    of analytic spectra, scene/city/surfaces.py), with `wet_road_fraction` of the road under
    puddles; `paint` 'diffuse' (paints Lambertian, as before) or 'clearcoat' (every 'paint_*'
    material under a glossy n = 1.5 clear coat: scene_builder.PAINT_COAT_*)."""

    lighting: Literal["day", "night"] = Field("day", description="daylight (render.daylight) or night "
                                                                 "(night); city render")
    night: NightParams = Field(default_factory=NightParams, description="night lighting; city render")
    fog: FogParams | None = Field(None, description="fog or haze; None = clear air; city render")
    glass: Literal["diffuse", "dielectric"] = Field("diffuse", description="windows as dark diffuse surfaces or "
                                                                           "thin glass panes; city render")
    materials: Literal["uniform", "procedural"] = Field("uniform", description="one spectrum per material or "
                                                                         "procedural blends (wear, stains, "
                                                                         "bricks, soil, puddles); city render")
    wet_road_fraction: float = Field(0.05, ge=0.0, le=1.0, description="road area under puddles with procedural "
                                                                      "materials (0–1); city render")
    paint: Literal["diffuse", "clearcoat"] = Field("diffuse", description="vehicle paints Lambertian or under a "
                                                                          "glossy clear coat; city render")


class RenderParams(Params):
    """How to render spectral radiance with Mitsuba.

    representation: 'bands' = `band_count` box bands over the wavelength range (output at band
    centres); 'basis' = `basis_count` smooth raised-cosine functions, projected back onto an
    `output_step_nm` grid; 'sensor' = the sensor's own channel QE curves as film responses
    (output = QE-weighted mean radiance per channel).
    Sampling: exactly one of `spp` (fixed samples per pixel), `target_rel_error` (relative RMS
    error wanted, spp = (c/e)² with c measured by a pilot render on this scene; `error_metric`
    chooses broadband (channel sum) or the mean per-channel error) or `shot_noise_ratio` (render
    noise = this fraction of the photon shot noise 1/√N_e of the sensor's exposure, N_e measured on
    a pilot render through the project's optics and sensor; 0.3 adds ≈ 4 % to the total noise). Rendering runs in chunks of
    `chunk_spp` after a `preview_spp` preview, checking for cancellation between chunks.
    Sampler: 'independent' (noise ∝ 1/√spp) or the stratified 'multijitter' and low-discrepancy
    'ldsampler', which stratify the samples of one chunk: on the detection city at 128 spp in one
    chunk, multijitter's median per-pixel error is a quarter of independent's (`workbench
    dataset-noise`); give preview_spp = chunk_spp = spp to stratify them all.
    Wavelength range: `wavelength_min_nm`/`wavelength_max_nm`, or None to follow the sensor's QE
    (400–700 nm when no sensor is given); 'sensor' always uses the QE curves' own range."""

    representation: Literal["bands", "basis", "sensor"] = Field(
        "bands", description="spectral film: box bands, smooth basis functions or the sensor's own channel "
                             "QE curves; city render")
    band_count: int = Field(16, ge=1, le=128, description="box bands over the wavelength range (count); "
                                                          "representation 'bands'")
    basis_count: int = Field(6, ge=2, le=32, description="raised-cosine basis functions (count); "
                                                         "representation 'basis'")
    output_step_nm: float = Field(10.0, gt=0.0, le=100.0, description="output wavelength step (nm); "
                                                                      "representation 'basis'")
    wavelength_min_nm: float | None = Field(None, ge=350.0, le=1000.0,
                                            description="render range start (nm); None follows the sensor's QE")
    wavelength_max_nm: float | None = Field(None, ge=350.0, le=1000.0,
                                            description="render range end (nm); None follows the sensor's QE")
    spp: int | None = Field(64, ge=1, le=1 << 20, description="fixed samples per pixel (count); city render")
    target_rel_error: float | None = Field(None, gt=0.0, lt=1.0,
                                           description="relative RMS render error wanted (0–1), spp from a pilot "
                                                       "render; city render")
    shot_noise_ratio: float | None = Field(None, gt=0.0, le=10.0,
                                           description="render noise as this fraction of the sensor's photon shot "
                                                       "noise (unitless); city render through optics and sensor")
    error_metric: Literal["broadband", "per_channel"] = Field(
        "broadband", description="error of target_rel_error: channel sum or mean per channel; city render")
    pilot_spp: int = Field(4, ge=1, le=256, description="samples per pixel of each pilot render (count)")
    max_spp: int = Field(16384, ge=1, le=1 << 20, description="most samples per pixel an error target may ask (count)")
    max_depth: int = Field(6, ge=1, le=64, description="longest light path (bounces); Mitsuba integrator")
    sampler: Literal["independent", "multijitter", "ldsampler"] = Field(
        "independent", description="Mitsuba sampler: independent, or stratified within each chunk; city render")
    chunk_spp: int = Field(16, ge=1, le=1 << 16, description="samples per pixel per chunk between progress "
                                                             "and cancel checks (count)")
    preview_spp: int = Field(1, ge=1, le=1 << 16, description="samples per pixel of the first preview chunk (count)")
    seed: int = Field(0, ge=0, lt=2**32, description="render noise seed (a data-set frame derives its own)")
    variant: Literal["cuda_ad_spectral", "llvm_ad_spectral", "scalar_spectral"] | None = Field(
        None, description="Mitsuba variant; None picks the fastest available (render.variants)")
    daylight: DaylightParams = Field(default_factory=DaylightParams, description="sun and sky; city render")
    world: WorldParams = Field(default_factory=WorldParams, description="lighting, fog and glass; city render")

    @model_validator(mode="after")
    def _check(self) -> "RenderParams":
        chosen = [n for n in ("spp", "target_rel_error", "shot_noise_ratio") if getattr(self, n) is not None]
        if len(chosen) != 1:
            raise InvalidValueError(f"give exactly one of spp ({self.spp}), target_rel_error ({self.target_rel_error}) "
                             f"or shot_noise_ratio ({self.shot_noise_ratio}); set the others to None")
        lo, hi = self.wavelength_min_nm, self.wavelength_max_nm
        if (lo is None) != (hi is None):
            raise InvalidValueError("wavelength_min_nm and wavelength_max_nm must both be set or both None")
        if lo is not None and hi - lo < 1.0:
            raise InvalidValueError(f"wavelength_max_nm ({hi}) must exceed wavelength_min_nm ({lo}) by ≥ 1 nm")
        return self
