"""The project's camera geometry: the one CameraGeometry its scene, optics and keys use."""
from __future__ import annotations

from workbench.optics.formation.geometry import CameraGeometry, camera_geometry


def project_geometry(project) -> CameraGeometry:
    """Sensor rows × cols × scene.oversample samples behind the project's optics, focused on
    optics.focus_distance_m or else scene.distance_m. The samples span the sensor
    (cols × pixel pitch, so their spacing is pixel pitch / oversample), or scene.fov_deg at the
    image distance when the scene gives one (the sensor stage then resamples)."""
    over, sensor, scene = project.scene.oversample, project.sensor, project.scene
    shape = (sensor.rows * over, sensor.cols * over)
    if scene.fov_deg is not None:
        return camera_geometry(project.optics, scene.distance_m, shape, fov_deg=scene.fov_deg)
    return camera_geometry(project.optics, scene.distance_m, shape,
                           sensor_width_m=sensor.cols * sensor.pixel_pitch_um * 1e-6)
