"""Parameters of the procedural city (`CityRecipe`), of the camera poses (`PoseParams`) and the
label classes (`CLASS_IDS`).

Street geometry: a grid of blocks_x × blocks_y square blocks of block_size_m (kerb to kerb, the
sidewalk ring included) separated by two-way streets of 2·lanes_per_direction lanes. Traffic
keeps to the right. Counts (n_cars …) are per arrangement: the arrangement index changes where
the movable objects and street furniture go, never the streets or the buildings.
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from workbench.errors import InvalidValueError
from workbench.params import Params

# Label classes (COCO category ids); 0 is background/sky and is not a category.
BACKGROUND_ID = 0
CLASS_IDS: dict[str, int] = {
    "car": 1,
    "pedestrian": 2,
    "bus": 3,
    "truck": 4,
    "building": 5,
    "tree": 6,
    "lamp": 7,
    "bench": 8,
    "mailbox": 9,
    "road": 10,
    "sidewalk": 11,
    "marking": 12,
    "ground": 13,
    "tunnel": 14,
}

# Smallest building lot left inside a block once the sidewalk ring is taken off (m).
MIN_LOT_M = 20.0
# Depth of the ring of distant buildings (skyline_distance_m; scene/city/skyline.py), m.
SKYLINE_DEPTH_M = 60.0


class TunnelParams(Params):
    """A straight road tunnel over one street segment (scene/city/tunnel.py): the street along +Y at
    x = street_index · pitch, between cross streets segment_index and segment_index + 1, centred on
    the segment. Concrete side walls stand behind both sidewalks (which become its walkways), a
    flat roof slab spans them at clearance_m above the road; the open ends are the portals.
    Luminaires hang in one continuous row over the centre line, one every luminaire_spacing_m, each a
    glowing Lambertian lens luminaire_length_m long (0.4 m across) of luminaire_flux_lm
    (render/luminaire_row.py), lit by day and by night.

    Defaults: a continuous line of 1.5 m luminaires mounted end to end at a 1.6 m pitch, as the
    interior zones of road tunnels are lit ("line lighting": luminaires of one or two 1,500 mm
    T8/T5-length tubes or their LED successors butted into a line; a continuous line casts no
    flicker, which van Bommel, Road Lighting, Springer 2015, §20 / Fig. 20.19 puts as disturbing
    between 2.5 and 15 Hz, i.e. for discrete luminaires at 1.9–11 m spacing at 100 km/h), each of
    4,000 lm (a 58 W T8 tube's ~5,200 lm at a light output ratio of ~0.75): 2,500 lm per metre of
    tunnel, as the former row of 20,000 lm every 8 m. Road level follows CIE 88:2004's interior
    zone (a few cd/m² for urban traffic): a long row of Lambertian luminaires of flux Φ (on-axis
    intensity Φ/π) at spacing S and height h gives the road below E ≈ Σ (Φ/π) h²/r⁴ ≈ Φ/(2 S h),
    and a Lambertian asphalt of reflectance ρ ≈ 0.075 shows L = ρE/π; Φ/S = 2,500 lm/m,
    h ≈ 4.85 m → E ≈ 260 lx, L ≈ 6 cd/m² (the walls' inter-reflection adds a little)."""

    street_index: int = Field(1, ge=0, le=20, description="which street along +Y (0 = westmost) the tunnel "
                                                          "covers (count); city tunnel")
    segment_index: int = Field(0, ge=0, le=19, description="which segment of that street, from the south "
                                                           "(count); city tunnel")
    length_m: float = Field(80.0, ge=10.0, le=480.0, description="portal to portal (m); city tunnel")
    clearance_m: float = Field(5.0, ge=4.0, le=10.0, description="roof soffit above the road (m); city tunnel")
    wall_thickness_m: float = Field(0.5, gt=0.0, le=0.9, description="side wall thickness (m); city tunnel")
    roof_thickness_m: float = Field(1.0, gt=0.0, le=5.0, description="roof slab thickness (m); city tunnel")
    luminaire_kind: Literal["led", "hps"] = Field("led", description="luminaire spectrum; city tunnel lighting")
    luminaire_flux_lm: float = Field(4000.0, gt=0.0, le=1e6, description="luminous flux per luminaire (lm); "
                                                                          "city tunnel lighting")
    luminaire_spacing_m: float = Field(1.6, ge=0.5, le=100.0, description="luminaire spacing (pitch) along the "
                                                                          "tunnel (m); city tunnel lighting")
    luminaire_length_m: float = Field(1.5, ge=0.1, le=100.0, description="length of each luminaire's glowing lens "
                                                                         "along the tunnel (m), at most the "
                                                                         "spacing; city tunnel lighting")

    @model_validator(mode="after")
    def _check_luminaires(self) -> "TunnelParams":
        if self.luminaire_length_m > self.luminaire_spacing_m:
            raise InvalidValueError(f"tunnel luminaire_length_m={self.luminaire_length_m} exceeds luminaire_spacing_m="
                                    f"{self.luminaire_spacing_m}: the lenses would overlap; shorten them or space "
                                    "them wider")
        return self


class CityRecipe(Params):
    """Everything that determines a generated city; the same recipe gives the same city."""

    seed: int = Field(0, ge=0, description="seed of streets, buildings and placements; city generator")
    arrangement: int = Field(0, ge=0, description="placement index: changes objects, not buildings (a data-set "
                                                  "frame sets its own); city generator")
    blocks_x: int = Field(2, ge=1, le=20, description="blocks along +X (count); city layout")
    blocks_y: int = Field(2, ge=1, le=20, description="blocks along +Y (count); city layout")
    block_size_m: float = Field(100.0, gt=0, le=500.0, description="block side, sidewalks included (m); city layout")
    lane_width_m: float = Field(3.5, ge=2.5, le=5.0, description="lane width (m); city layout, camera poses")
    lanes_per_direction: int = Field(1, ge=1, le=3, description="lanes each way (count); city layout")
    sidewalk_width_m: float = Field(4.0, ge=2.0, le=12.0, description="sidewalk width (m); city layout, placement")
    curb_height_m: float = Field(0.15, ge=0.0, le=0.3, description="sidewalk top above the road (m); city geometry")
    ground_margin_m: float = Field(30.0, ge=0.0, le=500.0, description="grass beyond the outer streets (m); "
                                                                      "city geometry")
    horizon_field_m: float = Field(0.0, ge=0.0, le=5000.0, description=(
        "a flat field this wide (m) around the grass margin, so the ground reaches nearly to the horizon "
        "instead of ending where the perez and overcast skies are black; 0 = none; ≤ 5,000 m keeps it nearer than "
        "the sky's background depth; city geometry"))
    skyline_distance_m: float = Field(0.0, ge=0.0, le=4900.0, description=(
        "a ring of distant buildings (60 m deep) this far (m) beyond the grass margin, standing on the horizon "
        "field, so views out of the city end in buildings; 0 = none; city geometry"))
    building_height_min_m: float = Field(8.0, ge=3.0, le=400.0, description="lowest building (m); city buildings")
    building_height_max_m: float = Field(40.0, ge=3.0, le=400.0, description="tallest building (m); city buildings")
    asset_detail: Literal["simple", "detailed"] = Field(
        "simple", description="object geometry: 'simple' (the original low-detail assets) or 'detailed' (the "
                              "builders registered in scene.city.catalog.DETAILED_BUILDERS); city generator")
    n_cars: int = Field(16, ge=0, le=2000, description="cars per arrangement (count); placement")
    n_parked_cars: int = Field(0, ge=0, le=2000, description="cars parked along the kerb per arrangement, in "
                                                          "the kerb lanes (count); placement")
    n_pedestrians: int = Field(24, ge=0, le=5000, description="pedestrians per arrangement (count); placement")
    n_buses: int = Field(2, ge=0, le=200, description="buses per arrangement (count); placement")
    n_trucks: int = Field(1, ge=0, le=200, description="trucks per arrangement (count); placement")
    n_trees: int = Field(24, ge=0, le=5000, description="trees per arrangement (count); placement")
    n_lamps: int = Field(16, ge=0, le=5000, description="street lamps per arrangement (count); placement")
    n_benches: int = Field(8, ge=0, le=5000, description="benches per arrangement (count); placement")
    n_mailboxes: int = Field(4, ge=0, le=5000, description="mailboxes per arrangement (count); placement")
    tunnel: TunnelParams | None = Field(None, description="a road tunnel over one street segment; None = no "
                                                          "tunnel; city generator")

    @model_validator(mode="after")
    def _check_consistent(self) -> "CityRecipe":
        if self.building_height_min_m > self.building_height_max_m:
            raise InvalidValueError(
                f"building_height_min_m ({self.building_height_min_m}) must not exceed "
                f"building_height_max_m ({self.building_height_max_m})")
        lot = self.block_size_m - 2 * self.sidewalk_width_m
        if lot < MIN_LOT_M:
            raise InvalidValueError(
                f"block_size_m={self.block_size_m} leaves a {lot:.1f} m building lot after two "
                f"sidewalks of sidewalk_width_m={self.sidewalk_width_m}; need block_size_m >= "
                f"{2 * self.sidewalk_width_m + MIN_LOT_M:.1f}")
        if self.skyline_distance_m > 0 and self.horizon_field_m < self.skyline_distance_m + SKYLINE_DEPTH_M:
            raise InvalidValueError(
                f"skyline_distance_m={self.skyline_distance_m} puts the distant buildings ({SKYLINE_DEPTH_M:.0f} m "
                f"deep) beyond the horizon field of horizon_field_m={self.horizon_field_m}; set horizon_field_m "
                f">= {self.skyline_distance_m + SKYLINE_DEPTH_M:.0f} or lower skyline_distance_m")
        t = self.tunnel
        if t is not None:
            if t.street_index > self.blocks_x or t.segment_index >= self.blocks_y:
                raise InvalidValueError(f"tunnel street_index={t.street_index}, segment_index={t.segment_index}: the "
                                 f"city has streets 0…{self.blocks_x} along +Y with segments 0…{self.blocks_y - 1}")
            room = self.block_size_m - 2 * self.sidewalk_width_m
            if t.length_m > room:
                raise InvalidValueError(f"tunnel length_m={t.length_m} does not fit its street segment: at most "
                                 f"block_size_m − 2·sidewalk_width_m = {room:.1f} m (clear of the cross "
                                 "streets' sidewalks)")
        return self

    @property
    def street_width_m(self) -> float:
        """Carriageway width kerb to kerb (m): both directions' lanes."""
        return 2 * self.lanes_per_direction * self.lane_width_m

    @property
    def pitch_m(self) -> float:
        """Distance between neighbouring street centre lines (m)."""
        return self.block_size_m + self.street_width_m


class PoseParams(Params):
    """Camera poses as in the paper: 1.5 m above the road in a lane, pan about the lane direction.

    'random': position uniform along a random lane (lateral jitter ≤ lateral_jitter_m), pan =
    lane heading + U(pan_range_deg), tilt U(tilt_range_deg), roll U(roll_range_deg).
    'target': like the paper's camera generator (a camera ~10 m from a target object): pick a
    class of target_classes (equally likely), then one of its objects; put the camera in a lane
    at a distance in target_distance_range_m, the target within max_target_bearing_deg of the
    lane direction; pan = bearing to the target + U(pan_range_deg); tilt, roll as in 'random'.
    'manual': manual_position_xy_m at height_m above the road, manual_* angles; manual_pan_deg
    is the absolute yaw about +Z from +X (the `CameraPose` convention).
    'tunnel' (a city with CityRecipe.tunnel): in a lane of the tunnel's street, heading along it,
    tunnel_distance_range_m before the portal ahead: the exit portal from inside the tunnel
    (tunnel_view 'exit') or the entrance portal from outside ('entrance'); pan jitter, tilt, roll
    as in 'random'."""

    mode: Literal["random", "target", "manual", "tunnel"] = Field("random", description="how poses are chosen "
                                                                                       "(see the class doc); "
                                                                                       "camera poses")
    height_m: float = Field(1.5, gt=0.0, le=50.0, description="camera height above the road (m); camera poses")
    pan_range_deg: tuple[float, float] = Field((-10.0, 10.0), description="(low, high) pan jitter (deg); "
                                                                          "random and target poses")
    tilt_range_deg: tuple[float, float] = Field((-5.0, 5.0), description="(low, high) tilt (deg); random and "
                                                                         "target poses")
    roll_range_deg: tuple[float, float] = Field((-5.0, 5.0), description="(low, high) roll (deg); random and "
                                                                         "target poses")
    lateral_jitter_m: float = Field(0.3, ge=0.0, le=1.0, description="offset from the lane centre (m); camera poses")
    target_classes: tuple[str, ...] = Field(("car", "bus", "truck", "pedestrian"),
                                            description="object classes a target pose aims at; target poses")
    target_distance_range_m: tuple[float, float] = Field((8.0, 12.0), description="(low, high) camera-to-target "
                                                                                  "distance (m); target poses")
    max_target_bearing_deg: float = Field(45.0, gt=0.0, le=180.0,
                                          description="target direction vs lane direction (deg); target poses")
    tunnel_view: Literal["exit", "entrance"] = Field("exit", description="inside looking at the exit or outside "
                                                                         "approaching the entrance; tunnel poses")
    tunnel_distance_range_m: tuple[float, float] = Field((20.0, 60.0), description="(low, high) camera-to-portal "
                                                                                   "distance (m); tunnel poses")
    manual_position_xy_m: tuple[float, float] | None = Field(None, description="(x, y) camera position (m); "
                                                                               "manual pose")
    manual_pan_deg: float = Field(0.0, ge=-360.0, le=360.0, description="yaw about +Z from +X (deg); manual pose")
    manual_tilt_deg: float = Field(0.0, ge=-90.0, le=90.0, description="tilt, up positive (deg); manual pose")
    manual_roll_deg: float = Field(0.0, ge=-180.0, le=180.0, description="roll (deg); manual pose")
    seed: int = Field(0, ge=0, description="pose sampling seed (a data-set frame derives its own); camera poses")
    poses_per_arrangement: int = Field(1, ge=1, le=64, description=(
        "consecutive data-set frames that share one city arrangement, each from its own camera pose: a worker "
        "keeps the loaded city and renders the next pose without building the scene again; a city is all "
        "train or all test frames; data-set frames"))

    @model_validator(mode="after")
    def _check_ranges(self) -> "PoseParams":
        limits = {"pan_range_deg": 180.0, "tilt_range_deg": 90.0, "roll_range_deg": 180.0}
        for name, lim in limits.items():
            lo, hi = getattr(self, name)
            if not (-lim <= lo <= hi <= lim):
                raise InvalidValueError(f"{name}=({lo}, {hi}) must satisfy -{lim} <= low <= high <= {lim}")
        unknown = [c for c in self.target_classes if c not in CLASS_IDS]
        if unknown or not self.target_classes:
            raise InvalidValueError(f"target_classes={self.target_classes!r}: need one or more of "
                             f"{', '.join(CLASS_IDS)}")
        lo, hi = self.target_distance_range_m
        if not 0 < lo <= hi <= 500:
            raise InvalidValueError(f"target_distance_range_m=({lo}, {hi}) must satisfy 0 < low <= high <= 500")
        lo, hi = self.tunnel_distance_range_m
        if not 0 < lo <= hi <= 500:
            raise InvalidValueError(f"tunnel_distance_range_m=({lo}, {hi}) must satisfy 0 < low <= high <= 500")
        if self.mode == "manual" and self.manual_position_xy_m is None:
            raise InvalidValueError("mode='manual' needs manual_position_xy_m=(x, y) in metres")
        return self
