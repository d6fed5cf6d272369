"""Draw a city on any pyvista plotter (the GUI's QtInteractor or an off-screen Plotter).

Meshes are merged per material (one actor each, so hundreds of objects draw fast) and coloured by
the sRGB of the material's reflectance under D65.
"""
from __future__ import annotations

import numpy as np

from workbench.scene.city.poses import pose_basis
from workbench.scene.city.types import CameraPose, City, Material
from workbench.spectra import illuminant_spd, xyz_cmfs


def material_srgb(material: Material) -> np.ndarray:
    """sRGB (0…1, gamma-encoded) of a reflectance lit by D65, white = perfect diffuser."""
    import colour
    wl = np.asarray(material.wavelengths_nm, dtype=np.float64)
    cmfs, d65 = xyz_cmfs(wl), illuminant_spd("D65", wl)
    xyz = (np.asarray(material.reflectance) * d65) @ cmfs / (d65 @ cmfs[:, 1])
    return np.clip(colour.XYZ_to_sRGB(xyz), 0.0, 1.0)


def _polydata(vertices: list[np.ndarray], faces: list[np.ndarray]):
    import pyvista as pv
    offsets = np.cumsum([0] + [len(v) for v in vertices[:-1]])
    f = np.concatenate([fc + o for fc, o in zip(faces, offsets)])
    cells = np.column_stack([np.full(len(f), 3), f]).astype(np.int64).ravel()
    return pv.PolyData(np.concatenate(vertices), cells)


# Distinct colours of the label classes for "colour by class" (sRGB 0…1).
CLASS_COLOURS: dict[str, tuple[float, float, float]] = {
    "car": (0.90, 0.10, 0.10), "pedestrian": (1.00, 0.55, 0.00), "bus": (0.95, 0.85, 0.10),
    "truck": (0.60, 0.20, 0.80), "building": (0.55, 0.60, 0.70), "tree": (0.15, 0.65, 0.20),
    "lamp": (0.10, 0.80, 0.90), "bench": (0.55, 0.35, 0.15), "mailbox": (0.10, 0.30, 0.95),
    "road": (0.25, 0.25, 0.25), "sidewalk": (0.70, 0.70, 0.65), "marking": (1.00, 1.00, 1.00),
    "ground": (0.45, 0.70, 0.35),
}


def add_city_to_plotter(plotter, city: City, pose: CameraPose | None = None,
                        set_view: bool = False, hfov_deg: float = 44.0,
                        frustum_length_m: float = 6.0, color_by: str = "material") -> dict:
    """Add the city's meshes to `plotter`; with a pose, also a wireframe view frustum (hfov_deg,
    4:3) at the camera, or, with set_view=True, look through that pose instead.

    color_by 'material' merges meshes per material coloured by its sRGB under D65; 'class' merges
    them per label class coloured by CLASS_COLOURS. Returns the actors by material (or class)
    name (plus 'camera' for the frustum)."""
    if color_by not in ("material", "class"):
        raise ValueError(f"color_by must be 'material' or 'class', given {color_by!r}")
    groups: dict[str, tuple[list, list]] = {}
    for obj in city.objects:
        for m in obj.meshes:
            if len(m.faces):
                vs, fs = groups.setdefault(m.material if color_by == "material" else obj.class_name, ([], []))
                vs.append(m.vertices)
                fs.append(m.faces)
    actors = {}
    for name in sorted(groups):
        if color_by == "class":
            colour_rgb = CLASS_COLOURS.get(name, (0.8, 0.8, 0.8))
        elif name not in city.materials:
            raise ValueError(f"mesh material '{name}' is not in city.materials")
        else:
            colour_rgb = material_srgb(city.materials[name])
        actors[name] = plotter.add_mesh(_polydata(*groups[name]), color=colour_rgb,
                                        name=f"city_{name}", smooth_shading=False)
    if pose is None:
        return actors
    if set_view:
        look_through(plotter, pose, hfov_deg)
        return actors
    actors["camera"] = add_camera_frustum(plotter, pose, hfov_deg, frustum_length_m)
    return actors


def look_through(plotter, pose: CameraPose, hfov_deg: float = 44.0) -> None:
    """Set the plotter's view to the camera's (position, direction, up and 4:3 vertical angle)."""
    f, _right, up = pose_basis(pose)
    plotter.camera.position = tuple(pose.position_m)
    plotter.camera.focal_point = tuple(pose.position_m + 10.0 * f)
    plotter.camera.up = tuple(up)
    plotter.camera.view_angle = float(np.degrees(2 * np.arctan(0.75 * np.tan(np.radians(hfov_deg) / 2))))


def add_camera_frustum(plotter, pose: CameraPose, hfov_deg: float = 44.0, frustum_length_m: float = 6.0):
    """A wireframe view frustum (hfov_deg, 4:3) at the camera; returns its actor ('city_camera')."""
    import pyvista as pv
    f, right, up = pose_basis(pose)
    half_w = frustum_length_m * np.tan(np.radians(hfov_deg) / 2)
    apex = np.asarray(pose.position_m, dtype=np.float64)
    base = [apex + frustum_length_m * f + sx * half_w * right + sy * 0.75 * half_w * up
            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    pts = np.vstack([apex] + base)
    lines = np.array([2, 0, 1, 2, 0, 2, 2, 0, 3, 2, 0, 4, 5, 1, 2, 3, 4, 1])
    return plotter.add_mesh(pv.PolyData(pts, lines=lines), color=(1.0, 0.1, 0.6),
                            name="city_camera", line_width=3)
