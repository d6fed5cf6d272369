"""Draw a city on any pyvista plotter (the window's off-screen 3-D view, or any Plotter).

All meshes are merged into one PolyData (city_polydata, which needs no plotter, so it can be
built on a worker thread) carrying two per-cell colourings: 'material_rgb' (the sRGB of each
material's reflectance under D65) and 'class_rgb' (CLASS_COLOURS). One actor draws the city, and
switching the colouring is a change of its active scalars, not a rebuild; the camera frustum is
one actor whose points move with the camera (move_camera_frustum).
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
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


COLOURINGS = {"material": "material_rgb", "class": "class_rgb"}


def city_polydata(city: City):
    """The whole city as one triangle PolyData with uint8 cell colours 'material_rgb' and
    'class_rgb' and the cell's material name index 'material_id' (into sorted(city.materials))."""
    vertices, faces, material_rgb, class_rgb = [], [], [], []
    srgb = {}
    for obj in city.objects:
        cls = np.round(255 * np.asarray(CLASS_COLOURS.get(obj.class_name, (0.8, 0.8, 0.8)))).astype(np.uint8)
        for m in obj.meshes:
            if not len(m.faces):
                continue
            if m.material not in city.materials:
                raise InvalidValueError(f"mesh material '{m.material}' is not in city.materials")
            if m.material not in srgb:
                srgb[m.material] = np.round(255 * material_srgb(city.materials[m.material])).astype(np.uint8)
            vertices.append(m.vertices)
            faces.append(m.faces)
            material_rgb.append(np.broadcast_to(srgb[m.material], (len(m.faces), 3)))
            class_rgb.append(np.broadcast_to(cls, (len(m.faces), 3)))
    mesh = _polydata(vertices, faces)
    mesh.cell_data["material_rgb"] = np.concatenate(material_rgb)
    mesh.cell_data["class_rgb"] = np.concatenate(class_rgb)
    return mesh


def add_city_to_plotter(plotter, city: City | None = None, pose: CameraPose | None = None,
                        set_view: bool = False, hfov_deg: float = 44.0,
                        frustum_length_m: float = 6.0, color_by: str = "material", mesh=None) -> dict:
    """Add the city (or its prebuilt city_polydata `mesh`) to `plotter` as one actor 'city'
    coloured by `color_by` ('material' | 'class'); with a pose, also a wireframe view frustum
    ('camera': hfov_deg, 4:3) at the camera, or, with set_view=True, look through that pose
    instead. Returns the actors by name."""
    if color_by not in COLOURINGS:
        raise InvalidValueError(f"color_by must be 'material' or 'class', given {color_by!r}")
    mesh = city_polydata(city) if mesh is None else mesh
    actors = {"city": plotter.add_mesh(mesh, scalars=COLOURINGS[color_by], rgb=True, name="city_mesh",
                                       smooth_shading=False, show_scalar_bar=False)}
    if pose is None:
        return actors
    if set_view:
        look_through(plotter, pose, hfov_deg)
        return actors
    actors["camera"] = add_camera_frustum(plotter, pose, hfov_deg, frustum_length_m)
    return actors


def set_city_colouring(actor, color_by: str) -> None:
    """Switch a city actor between the colourings of city_polydata (no rebuild)."""
    if color_by not in COLOURINGS:
        raise InvalidValueError(f"color_by must be 'material' or 'class', given {color_by!r}")
    mapper = actor.mapper
    mapper.dataset.cell_data.active_scalars_name = COLOURINGS[color_by]
    mapper.SetScalarModeToUseCellFieldData()
    mapper.SelectColorArray(COLOURINGS[color_by])
    mapper.SetColorModeToDirectScalars()


def look_through(plotter, pose: CameraPose, hfov_deg: float = 44.0) -> None:
    """Set the plotter's view to the camera's (position, direction, up and 4:3 vertical angle)."""
    f, _right, up = pose_basis(pose)
    plotter.camera.position = tuple(pose.position_m)
    plotter.camera.focal_point = tuple(pose.position_m + 10.0 * f)
    plotter.camera.up = tuple(up)
    plotter.camera.view_angle = float(np.degrees(2 * np.arctan(0.75 * np.tan(np.radians(hfov_deg) / 2))))


def frustum_points(pose: CameraPose, hfov_deg: float = 44.0, frustum_length_m: float = 6.0) -> np.ndarray:
    """The 5 corners (apex, then the far rectangle) of the camera's 4:3 view frustum."""
    f, right, up = pose_basis(pose)
    half_w = frustum_length_m * np.tan(np.radians(hfov_deg) / 2)
    apex = np.asarray(pose.position_m, dtype=np.float64)
    base = [apex + frustum_length_m * f + sx * half_w * right + sy * 0.75 * half_w * up
            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    return np.vstack([apex] + base)


def add_camera_frustum(plotter, pose: CameraPose, hfov_deg: float = 44.0, frustum_length_m: float = 6.0):
    """A wireframe view frustum (hfov_deg, 4:3) at the camera; returns its actor ('city_camera')."""
    import pyvista as pv
    lines = np.array([2, 0, 1, 2, 0, 2, 2, 0, 3, 2, 0, 4, 5, 1, 2, 3, 4, 1])
    return plotter.add_mesh(pv.PolyData(frustum_points(pose, hfov_deg, frustum_length_m), lines=lines),
                            color=(1.0, 0.1, 0.6), name="city_camera", line_width=3)


def move_camera_frustum(actor, pose: CameraPose, hfov_deg: float = 44.0, frustum_length_m: float = 6.0) -> None:
    """Move an add_camera_frustum actor to a new pose by changing its points only."""
    mesh = actor.mapper.dataset
    mesh.points = frustum_points(pose, hfov_deg, frustum_length_m)
    mesh.Modified()
