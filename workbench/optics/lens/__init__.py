"""Real lenses: prescriptions and glass, paraxial analysis, real-ray tracing, PSFs and aberrations.

Units: lengths in mm (prescriptions, rays), object distances in m (from the first vertex; inf =
infinity), wavelengths in nm, PSF grids in µm.
Coordinates: first vertex at z = 0, light travelling +z from object to image; the sensor plane is
at `sensor_z_mm(lens)` (last vertex + `lens.image_distance_mm`, or + BFL when that is None).
Fields: an angle θ rises towards +y and its chief ray lands at +y on the sensor; PSF arrays are
indexed [i, j] with i along +y and j along +x, centred on the chief ray at [size//2, size//2].
Invalid rays (misses, TIR, vignetting) are flagged by masks and carry finite placeholders.
The Mitsuba lens camera that traces these lenses is `workbench.render.lens_camera` (this package
does not need Mitsuba).
"""
from workbench.optics.lens.analysis import (Distortion, RayFan, SpotDiagram, axial_color, distortion,
                                            irradiance_per_radiance, lateral_color, ray_fan, real_fov_deg,
                                            relative_illumination, spot_diagram)
from workbench.optics.lens.glass import LINE_C_NM, LINE_D_NM, LINE_F_NM, Material, glass_catalogue, material
from workbench.optics.lens.io import available_lenses, load_lens, save_lens
from workbench.optics.lens.model import Lens, Surface
from workbench.optics.lens.paraxial import (ParaxialData, focus, image_distance_mm, paraxial,
                                            sensor_distance_mm, sensor_z_mm)
from workbench.optics.lens.psf import (diffraction_mtf, mtf_from_psf, psf_diffraction, psf_from_pupil,
                                       psf_geometric)
from workbench.optics.lens.pupil import chief_ray_on_sensor, field_angle_for_height
from workbench.optics.lens.trace import trace_from_object, trace_from_sensor, trace_rays

__all__ = [
    "Lens", "Surface", "Material", "material", "glass_catalogue", "LINE_C_NM", "LINE_D_NM", "LINE_F_NM",
    "load_lens", "save_lens", "available_lenses",
    "ParaxialData", "paraxial", "focus", "image_distance_mm", "sensor_distance_mm", "sensor_z_mm",
    "trace_rays", "trace_from_object", "trace_from_sensor", "chief_ray_on_sensor", "field_angle_for_height",
    "psf_geometric", "psf_diffraction", "psf_from_pupil", "mtf_from_psf", "diffraction_mtf",
    "spot_diagram", "SpotDiagram", "ray_fan", "RayFan", "distortion", "Distortion",
    "relative_illumination", "irradiance_per_radiance", "real_fov_deg", "lateral_color", "axial_color",
]
