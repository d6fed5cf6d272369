"""Procedural surfaces: city materials as blends of analytic spectra under scalar textures.

A `Surface` starts from a base material and lays `Layer`s over it in order: each layer blends
its own material in with weight w(u, v) from a baked texture (textures.py), i.e. reflectance
(1 − w)·ρ_below + w·ρ_layer. Every component is one of the city's analytic spectra (defined to
1,000 nm) and every weight is a scalar, so the blend stays spectrally exact. A `wet` layer is its
material under a smooth water film (n = 1.33): the renderer gives it a Fresnel-reflecting coat
whose trapped light darkens the substrate as Lekner & Dorf (1988, Appl. Opt. 27, 1278) derive
from Ångström's (1925) total internal reflection argument.

Texture coordinates are planar projections in metres (`planar_uv_m`): ground-facing faces use
(x, y); walls use (distance along the wall, z), so brick courses stay horizontal.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.scene.city.textures import BRICK_TILE_M, SLAB_M

WATER_IOR = 1.33


@dataclass(frozen=True)
class Texture:
    """A baked scalar texture (textures.bake arguments) repeated every tile_m metres."""

    kind: str
    tile_m: float
    size_px: int = 256
    fraction: float = 0.0
    strength: float = 1.0


@dataclass(frozen=True)
class Layer:
    """`material` blended over what lies below with weight `texture`; `wet`: under water."""

    texture: Texture
    material: str
    wet: bool = False


@dataclass(frozen=True)
class Surface:
    base: str
    layers: tuple[Layer, ...]


def procedural_surfaces(wet_fraction: float) -> dict[str, Surface]:
    """The city materials that become procedural surfaces, by material name. `wet_fraction` of
    the road lies under puddles (0 = dry)."""
    if not 0.0 <= wet_fraction <= 1.0:
        raise InvalidValueError(f"wet_fraction must be in 0…1, got {wet_fraction}")
    stains = Layer(Texture("stains", 16.0, 512, strength=0.6), "grime")
    joints = Layer(Texture("slab_joints", SLAB_M, 256, strength=0.8), "grime")
    asphalt = [Layer(Texture("asphalt_wear", 32.0, 1024), "asphalt_aged")]
    if wet_fraction > 0:
        asphalt.append(Layer(Texture("puddles", 32.0, 256, fraction=wet_fraction), "asphalt", wet=True))
    brick_tile = BRICK_TILE_M[0]
    return {
        "asphalt": Surface("asphalt", tuple(asphalt)),
        "concrete": Surface("concrete", (stains, joints)),
        "concrete_dark": Surface("concrete_dark", (stains,)),
        "sandstone": Surface("sandstone", (stains,)),
        "plaster_white": Surface("plaster_white", (Layer(Texture("streaks", 12.0, 512, strength=0.5), "grime"),)),
        "brick": Surface("brick", (Layer(Texture("brick_variation", brick_tile, 512, strength=0.7), "brick_dark"),
                                   Layer(Texture("brick_mortar", brick_tile, 512), "mortar"))),
        "grass": Surface("grass", (Layer(Texture("soil_patches", 24.0, 512, fraction=0.2), "soil"),)),
    }


def planar_uv_m(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unshared vertices (3F×3), faces (F×3) and per-vertex texture coordinates (3F×2, metres):
    faces whose normal is within 45° of vertical get (x, y); the others (walls) get (distance
    along the wall's horizontal tangent, z)."""
    v = np.asarray(vertices, dtype=np.float64)[np.asarray(faces).reshape(-1)]
    tri = v.reshape(-1, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    ground = np.abs(n[:, 2]) >= np.sqrt(0.5)
    tangent = np.stack([-n[:, 1], n[:, 0]], axis=1)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-30)
    along = np.einsum("fkj,fj->fk", tri[:, :, :2], tangent)
    uv = np.where(ground[:, None, None], tri[:, :, :2], np.stack([along, tri[:, :, 2]], axis=2))
    f = np.arange(len(v), dtype=np.int64).reshape(-1, 3)
    return v, f, uv.reshape(-1, 2)
