"""Procedural city: recipe → City (streets, buildings, vehicles, people, furniture with spectral
materials) and camera poses. See recipe.py for the parameters and CLASS_IDS for the labels."""
from workbench.scene.city.catalog import build_asset, variant_names
from workbench.scene.city.generate import generate_city
from workbench.scene.city.layout import CityLayout, Lane
from workbench.scene.city.materials import MATERIAL_WAVELENGTHS_NM, city_materials, reflectance
from workbench.scene.city.poses import pose_basis, sample_camera_poses
from workbench.scene.city.recipe import BACKGROUND_ID, CLASS_IDS, CityRecipe, PoseParams, TunnelParams
from workbench.scene.city.types import CameraPose, City, CityObject, Material, Mesh

__all__ = [
    "BACKGROUND_ID", "CLASS_IDS", "CameraPose", "City", "CityLayout", "CityObject", "CityRecipe",
    "Lane", "MATERIAL_WAVELENGTHS_NM", "Material", "Mesh", "PoseParams", "build_asset",
    "city_materials", "generate_city", "pose_basis", "reflectance", "sample_camera_poses", "TunnelParams",
    "variant_names",
]
