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


def add_city_to_plotter(plotter, city: City, pose: CameraPose | None = None,
                        set_view: bool = False, hfov_deg: float = 44.0,
                        frustum_length_m: float = 6.0) -> dict:
    """Add the city's meshes to `plotter`; with a pose, also a wireframe view frustum (hfov_deg,
    4:3) at the camera, or, with set_view=True, look through that pose instead.

    Returns the actors by material name (plus 'camera' for the frustum)."""
    by_mat: dict[str, tuple[list, list]] = {}
    for obj in city.objects:
        for m in obj.meshes:
            if len(m.faces):
                vs, fs = by_mat.setdefault(m.material, ([], []))
                vs.append(m.vertices)
                fs.append(m.faces)
    actors = {}
    for name in sorted(by_mat):
        if name not in city.materials:
            raise ValueError(f"mesh material '{name}' is not in city.materials")
        colour_rgb = material_srgb(city.materials[name])
        actors[name] = plotter.add_mesh(_polydata(*by_mat[name]), color=colour_rgb,
                                        name=f"city_{name}", smooth_shading=False)
    if pose is None:
        return actors
    f, right, up = pose_basis(pose)
    if set_view:
        plotter.camera.position = tuple(pose.position_m)
        plotter.camera.focal_point = tuple(pose.position_m + 10.0 * f)
        plotter.camera.up = tuple(up)
        plotter.camera.view_angle = float(np.degrees(2 * np.arctan(0.75 * np.tan(np.radians(hfov_deg) / 2))))
        return actors
    import pyvista as pv
    half_w = frustum_length_m * np.tan(np.radians(hfov_deg) / 2)
    apex = np.asarray(pose.position_m, dtype=np.float64)
    base = [apex + frustum_length_m * f + sx * half_w * right + sy * 0.75 * half_w * up
            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    pts = np.vstack([apex] + base)
    lines = np.array([2, 0, 1, 2, 0, 2, 2, 0, 3, 2, 0, 4, 5, 1, 2, 3, 4, 1])
    actors["camera"] = plotter.add_mesh(pv.PolyData(pts, lines=lines), color=(1.0, 0.1, 0.6),
                                        name="city_camera", line_width=3)
    return actors
