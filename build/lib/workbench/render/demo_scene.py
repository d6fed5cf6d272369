"""A tiny deterministic city for tests and benchmarks that must not depend on the city generator.

A 200 m square of ground, a building, two cars and a pedestrian (boxes), coloured with ColorChecker
reflectances (BabelColor, 380–730 nm; end values held out to 350–1000 nm)."""
from __future__ import annotations

import re

import numpy as np

from workbench.scene.city.types import CameraPose, City, CityObject, Material, Mesh
from workbench.spectra import macbeth_names, macbeth_reflectances

MATERIAL_WAVELENGTHS_NM = np.arange(350.0, 1001.0, 10.0)


def box_mesh(lo, hi, material: str) -> Mesh:
    """Closed axis-aligned box (12 triangles, outward winding) between corners lo and hi (m)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])])
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], dtype=np.int32)
    return Mesh(v, f, material)


def plane_mesh(half_size_m: float, z_m: float, material: str) -> Mesh:
    """Square horizontal plane centred on the origin, facing +Z."""
    s = half_size_m
    v = np.array([[-s, -s, z_m], [s, -s, z_m], [s, s, z_m], [-s, s, z_m]])
    return Mesh(v, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32), material)


def _materials() -> dict[str, Material]:
    wl = MATERIAL_WAVELENGTHS_NM
    refl = macbeth_reflectances(wl)
    names = [re.sub("[^a-z0-9]+", "_", n.lower()).strip("_") for n in macbeth_names()]
    return {n: Material(n, wl, r) for n, r in zip(names, refl)}


def demo_city() -> City:
    """Ground, one building, two cars and one pedestrian in front of a camera at the origin."""
    mats = _materials()
    objs = [
        CityObject("ground", 1, [plane_mesh(100.0, 0.0, "neutral_5_70_d")]),
        CityObject("building", 2, [box_mesh((25, -10, 0), (35, 15, 18), "moderate_red")]),
        CityObject("car", 3, [box_mesh((12, -4, 0), (16.5, -2.2, 1.5), "blue")]),
        CityObject("car", 4, [box_mesh((18, 1, 0), (22.5, 2.8, 1.5), "yellow")]),
        CityObject("pedestrian", 5, [box_mesh((9, 0.5, 0), (9.5, 1.0, 1.75), "foliage")]),
    ]
    return City(objs, mats, seed=0, extent_m=(-100.0, -100.0, 100.0, 100.0), meta={"name": "demo"})


def demo_pose() -> CameraPose:
    """Camera 1.5 m above the ground at the origin, looking along +X, slightly down."""
    return CameraPose(np.array([0.0, 0.0, 1.5]), pan_deg=0.0, tilt_deg=-3.0, roll_deg=0.0)
