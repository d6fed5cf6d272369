"""Renderer-independent description of a procedural city (what the Mitsuba adapter consumes).

Coordinates: metres, right-handed, Z up, the ground plane at z = 0; +X east, +Y north.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Material:
    """A Lambertian material with an explicit spectral reflectance.

    reflectance is sampled at wavelengths_nm and must stay physical (0…1) over the whole range
    any sensor might see (here 350–1000 nm), including the near infrared."""

    name: str
    wavelengths_nm: np.ndarray
    reflectance: np.ndarray


@dataclass
class Mesh:
    """Triangle mesh: vertices (V×3 float64, m), faces (F×3 int32), one material by name."""

    vertices: np.ndarray
    faces: np.ndarray
    material: str


@dataclass
class CityObject:
    """One labelled object (a car, a pedestrian, a building …) made of one or more meshes.

    class_name is the label class ('car', 'pedestrian', 'bus', 'truck', 'building', 'tree',
    'lamp', 'bench', 'mailbox', 'road', 'sidewalk', 'marking', 'ground', 'tunnel'; see CLASS_IDS);
    instance_id is unique in the city (> 0; 0 means background/sky). The meshes are in world
    coordinates."""

    class_name: str
    instance_id: int
    meshes: list[Mesh]
    footprint_xy: np.ndarray | None = None   # K×2 polygon of the ground footprint (m)
    meta: dict = field(default_factory=dict)


@dataclass
class CameraPose:
    """Camera position (m) and orientation: yaw (pan) about +Z from +X, pitch (tilt) up, roll (deg).

    Roll is a right-handed rotation about the viewing direction (positive leans the camera's up
    vector to its right); `workbench.scene.city.poses.pose_basis` gives forward/right/up.
    meta holds how the pose was made (mode, lane_index, lane_heading_deg, pan_offset_deg)."""

    position_m: np.ndarray
    pan_deg: float
    tilt_deg: float
    roll_deg: float
    meta: dict = field(default_factory=dict)

    def forward(self) -> np.ndarray:
        p, t = np.radians(self.pan_deg), np.radians(self.tilt_deg)
        return np.array([np.cos(t) * np.cos(p), np.cos(t) * np.sin(p), np.sin(t)])


@dataclass
class City:
    """A generated city: objects with labels, materials by name, and the seed that made it."""

    objects: list[CityObject]
    materials: dict[str, Material]
    seed: int
    extent_m: tuple[float, float, float, float]   # xmin, ymin, xmax, ymax
    meta: dict = field(default_factory=dict)
