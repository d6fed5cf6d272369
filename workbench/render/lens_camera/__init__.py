"""The real lens inside Mitsuba 3 (the full optics model): a Python `mi.Sensor` that traces every
camera ray through the lens.

Algorithm (PBRT's realistic camera): the film sample gives a point on the sensor plane; the aperture
sample picks a point in the exit-pupil box of that point's radial bin (boxes precomputed in numpy
and cached per lens, focus and film size); the ray from the film point to that point is traced
backwards through every surface with Dr.Jit arithmetic (vertex-relative intersection, Snell, masks
for misses and TIR); its weight is cos⁴θ · A_box / z_rear² (0 for rays that die, which leave the
entrance pupil along the paraxial chief ray of their film point, so label and depth casts through
this sensor still see the right pixel). With `weight="irradiance"` the film then holds
E = ∫ L cos⁴θ / z² dA, the camera equation (π L /(4N²) on axis for a uniform scene); with
`weight="radiance"` it is divided by the on-axis value so a uniform scene reads L at the centre,
as with the perspective camera.

Cost (llvm, `workbench bench lens-camera`): spheres are hit without a division and need no
normalised normal, flat surfaces refract with n = (0, 0, 1), arithmetic is fused and every lens
constant is a Python float, so a camera ray costs about 2× a perspective one in an empty scene.

Modules: pupil boxes in workbench.optics.lens.pupil_bins (numpy), the Dr.Jit reverse trace in
`kernels`, the plugin and its dict in `plugin`. `workbench.optics.formation.full_model` makes this
camera the full optics model of a project (render.city_frame, bench optics): the lens prepared as
optics.formation prepares it, and the film read as sensor irradiance.

Dispersive lenses trace the hero wavelength of Mitsuba's four spectral samples (weight 4 on it,
0 on the others); non-dispersive lenses trace once at the d line for all four.

Camera frame: the origin is the lens's entrance pupil, +z looks at the scene, +y is image-up and
+x image-left (as Mitsuba's perspective camera), so `to_world` is placed like a pinhole's.
The variant must be set before `lens_sensor_dict` is called (see workbench.render.variants); it must
be a JIT variant (llvm/cuda): the scalar variants would call Python once per sample.
"""
from workbench.render.lens_camera.plugin import PLUGIN_NAME, lens_sensor_dict, register_lens_sensor

__all__ = ["PLUGIN_NAME", "lens_sensor_dict", "register_lens_sensor"]
