"""What a design-study grid may vary: the fields each optics level reads, a default grid that
varies what the project's model uses, and a word on every varied field the model ignores.

A design study (metrics.study) of a field no design's optics level reads would measure the same
camera several times and let the user read a trade that is not there; such a grid is refused.
A field a level reads only in part is flagged: the pinhole level has no blur, so its f-number sets
the irradiance (exposure, SNR) but not the MTF.
"""
from __future__ import annotations

from workbench.errors import ParameterError

LENS_FREE = frozenset({"pinhole", "diffraction_limited", "thin_lens"})
# optics fields read by only some levels ('auto' may pick any level, so it reads them all)
OPTICS_FIELD_LEVELS = {
    "off_axis": LENS_FREE, "distortion_k": LENS_FREE,
    "lens_file": frozenset({"psf_grid", "raytrace"}), "scale_lens_to_focal_length": frozenset({"psf_grid", "raytrace"}),
    "depth_layers": frozenset({"thin_lens"}), "defocus_kernel": frozenset({"thin_lens"}),
    "psf_field_zones": frozenset({"psf_grid"}), "psf_azimuths": frozenset({"psf_grid"}),
    "psf_wavelengths": frozenset({"psf_grid"}), "psf_depth_nodes": frozenset({"psf_grid"}),
    "rays_per_sample": frozenset({"raytrace"}), "raytrace_diffraction": frozenset({"raytrace"}),
}
PARTLY_READ = {("pinhole", "optics.f_number"): "the pinhole level has no blur: the f-number sets only the "
                                                "irradiance (exposure and SNR change, the MTF does not)"}
BLURRING_GRID = "sensor.pixel_pitch_um=1.5,2,3\noptics.f_number=2,4,8"
PINHOLE_GRID = "sensor.pixel_pitch_um=1.5,2,3\nsensor.read_noise_V=0.0005,0.001,0.002"


def default_grid(project) -> str:
    """The panel's starting grid: pixel pitch × f-number where the optics level blurs with the
    f-number, pixel pitch × read noise for the pinhole level (which it would not)."""
    return PINHOLE_GRID if project.optics.model == "pinhole" else BLURRING_GRID


def check_grid(project, vary: dict[str, list]) -> list[str]:
    """Notes on the varied fields that some design's optics level reads only in part; a
    ParameterError naming the field when no design's level reads it."""
    levels = {str(v) for v in vary.get("optics.model", [project.optics.model])}
    reads_all = "auto" in levels
    notes = []
    for field in vary:
        section, _, name = field.partition(".")
        if section == "optics" and name in OPTICS_FIELD_LEVELS and not reads_all \
                and not levels & OPTICS_FIELD_LEVELS[name]:
            raise ParameterError(field, vary[field], "a field the designs' optics level reads: "
                                 f"{', '.join(sorted(levels))} ignores it (read by "
                                 f"{', '.join(sorted(OPTICS_FIELD_LEVELS[name]))}); vary optics.model too, or "
                                 "another field")
        notes += [f"{field}: {why}" for (level, f), why in PARTLY_READ.items() if f == field and level in levels]
    return notes
