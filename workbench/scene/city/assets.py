"""Procedural asset library: cars, pedestrians, buses, trucks, trees, lamps, benches, mailboxes.

Each variant is built once (cached) in local coordinates: metres, x forward, y left, z up, the
origin on the ground at the centre of the footprint (lamps: at the pole, the arm along +x).
Parts are keyed by material name; the placeholder PAINT is replaced by the instance's paint
when the asset is placed.
Dimensions follow published vehicle and body data (car classes from manufacturers' spec sheets,
city buses 12 m × 2.55 m × ~3.2 m (EU max width 2.55 m), anthropometric proportions after
Drillis & Contini 1966: shoulder at 0.818 H, hip 0.53 H, knee 0.285 H, chin 0.87 H).
"""
from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from workbench.errors import InvalidValueError
from workbench.scene.city import geometry as g
from workbench.scene.city.materials import CLOTHES, SKINS
from workbench.scene.city.types import Mesh

PAINT = "PAINT"


@dataclass(frozen=True)
class Asset:
    """A built variant: parts by material (local coordinates) and its bounding box (m)."""

    class_name: str
    variant: str
    parts: dict[str, g.Part]
    length_m: float      # along local x
    width_m: float       # along local y
    height_m: float      # along z

    def meshes(self, paint: str | None = None) -> list[Mesh]:
        """Local-coordinate meshes, PAINT replaced by `paint`."""
        out = []
        for mat, (v, f) in self.parts.items():
            if mat == PAINT:
                if paint is None:
                    raise InvalidValueError(f"{self.class_name} '{self.variant}' needs a paint material")
                mat = paint
            out.append(Mesh(v.copy(), f.copy(), mat))
        return out


def finish_asset(class_name: str, variant: str, parts: dict[str, list[g.Part]],
            centre_xy: bool = True) -> Asset:
    """Merge parts per material; put the origin at the footprint centre (or keep x, y as built)."""
    merged = {m: g.merge(p) for m, p in parts.items() if p}
    allv = np.concatenate([v for v, _ in merged.values()])
    lo, hi = allv.min(0), allv.max(0)
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]) if centre_xy \
        else np.array([0.0, 0.0, lo[2]])
    merged = {m: (v - centre, f) for m, (v, f) in merged.items()}
    size = hi - lo
    return Asset(class_name, variant, merged, float(size[0]), float(size[1]), float(size[2]))


# ---------------------------------------------------------------- cars
@dataclass(frozen=True)
class CarSpec:
    name: str
    length_m: float
    width_m: float
    height_m: float
    clearance_m: float
    belt_m: float        # beltline (bottom of the side windows)
    hood_m: float        # front of the body to the windscreen base
    rear_m: float        # rear of the body to the rear-window base (trunk or bed length)
    screen_run_m: float  # horizontal run of the windscreen
    back_run_m: float    # horizontal run of the rear window
    wheel_r_m: float
    wheelbase_m: float


CAR_SPECS: tuple[CarSpec, ...] = (
    CarSpec("sedan_compact", 4.45, 1.80, 1.44, 0.15, 0.92, 1.05, 0.85, 0.65, 0.55, 0.31, 2.65),
    CarSpec("sedan_mid", 4.85, 1.84, 1.45, 0.15, 0.93, 1.15, 0.95, 0.70, 0.60, 0.32, 2.83),
    CarSpec("sedan_large", 4.97, 1.88, 1.48, 0.15, 0.95, 1.20, 1.00, 0.72, 0.62, 0.33, 2.92),
    CarSpec("coupe", 4.60, 1.85, 1.40, 0.13, 0.90, 1.25, 0.85, 0.80, 0.75, 0.33, 2.70),
    CarSpec("hatch_small", 4.25, 1.80, 1.47, 0.15, 0.94, 0.90, 0.15, 0.60, 0.30, 0.31, 2.60),
    CarSpec("hatch_mid", 4.35, 1.81, 1.48, 0.15, 0.95, 0.95, 0.18, 0.62, 0.30, 0.31, 2.64),
    CarSpec("wagon", 4.80, 1.84, 1.50, 0.15, 0.95, 1.10, 0.15, 0.68, 0.25, 0.32, 2.82),
    CarSpec("suv_compact", 4.40, 1.85, 1.65, 0.20, 1.05, 0.95, 0.15, 0.60, 0.25, 0.34, 2.66),
    CarSpec("suv_mid", 4.75, 1.92, 1.70, 0.21, 1.08, 1.05, 0.15, 0.62, 0.22, 0.36, 2.85),
    CarSpec("crossover", 4.55, 1.86, 1.60, 0.19, 1.02, 1.00, 0.15, 0.62, 0.35, 0.34, 2.70),
    CarSpec("minivan", 4.95, 1.97, 1.70, 0.16, 1.00, 0.75, 0.10, 0.85, 0.15, 0.33, 3.00),
    CarSpec("pickup", 4.98, 1.86, 1.70, 0.23, 1.05, 1.10, 1.60, 0.60, 0.05, 0.36, 3.05),
    CarSpec("van_compact", 4.30, 1.80, 1.68, 0.17, 1.00, 0.70, 0.10, 0.70, 0.12, 0.32, 2.70),
)


def _car(spec: CarSpec) -> Asset:
    L, W, H = spec.length_m, spec.width_m, spec.height_m
    c, belt = spec.clearance_m, spec.belt_m
    xf, xr = L / 2, -L / 2
    nose = c + 0.55 * (belt - c)
    body = g.extrude_xz(np.array([
        [xr + 0.10, c], [xf - 0.15, c], [xf, c + 0.12], [xf, nose],
        [xf - 0.25, belt - 0.10], [xf - spec.hood_m, belt], [xr + spec.rear_m, belt],
        [xr, belt - 0.08], [xr, c + 0.10]]), -W / 2, W / 2)
    x_ws, x_rw = xf - spec.hood_m, xr + spec.rear_m
    x_rf, x_rr = x_ws - spec.screen_run_m, x_rw + spec.back_run_m
    top = H - 0.06
    glass = g.convex_solid(np.array([
        [x_rw, -(W / 2 - 0.04), belt], [x_ws, -(W / 2 - 0.04), belt],
        [x_ws, W / 2 - 0.04, belt], [x_rw, W / 2 - 0.04, belt],
        [x_rr, -(W / 2 - 0.17), top], [x_rf, -(W / 2 - 0.17), top],
        [x_rf, W / 2 - 0.17, top], [x_rr, W / 2 - 0.17, top]]))
    roof = g.box((x_rr + 0.02, -(W / 2 - 0.19), top - 0.02), (x_rf - 0.02, W / 2 - 0.19, H))
    r = spec.wheel_r_m
    wheels = [g.cylinder_y(r, s * (W / 2 - 0.24), s * (W / 2 - 0.005), (x, r))
              for x in (spec.wheelbase_m / 2 - 0.05, -spec.wheelbase_m / 2 - 0.05) for s in (-1, 1)]
    lamp_z = (nose - 0.16, nose - 0.02)
    heads = [g.box((xf - 0.20, s * (W / 2 - 0.30) - 0.16, lamp_z[0]),
                   (xf - 0.005, s * (W / 2 - 0.30) + 0.16, lamp_z[1])) for s in (-1, 1)]
    tails = [g.box((xr + 0.005, s * (W / 2 - 0.22) - 0.13, belt - 0.25),
                   (xr + 0.15, s * (W / 2 - 0.22) + 0.13, belt - 0.12)) for s in (-1, 1)]
    return finish_asset("car", spec.name, {PAINT: [body, roof], "glass_dark": [glass], "rubber": wheels,
                                      "lens_clear": heads, "lens_red": tails})


# ---------------------------------------------------------------- people
@dataclass(frozen=True)
class PersonSpec:
    name: str
    height_m: float
    shoulder_m: float    # biacromial breadth
    hip_m: float
    skin: str
    top: str
    bottom: str
    stride_m: float      # ankle offset of a walking pose (0 = standing)


def _person_specs() -> tuple[PersonSpec, ...]:
    bottoms = ("cloth_denim", "cloth_black", "cloth_khaki", "cloth_gray", "cloth_carbon")
    specs = []
    for i in range(24):
        h = 1.50 + 0.45 * ((i * 5) % 24) / 23
        broad = 0.92 + 0.16 * ((i * 7) % 4) / 3          # build factor
        specs.append(PersonSpec(
            f"person_{i:02d}", round(h, 3), round(0.225 * h * broad, 3), round(0.19 * h * broad, 3),
            SKINS[i % 3], CLOTHES[(i * 3) % len(CLOTHES)], bottoms[i % 5],
            0.0 if i % 3 == 2 else 0.12 + 0.08 * (i % 2)))
    return tuple(specs)


PERSON_SPECS = _person_specs()


def _limb(top_xyz, bottom_xyz, r_top, r_bottom, n=8) -> g.Part:
    return g.convex_solid(np.concatenate([
        g.ring(r_top, r_top, top_xyz[2], n, top_xyz[:2]),
        g.ring(r_bottom, r_bottom, bottom_xyz[2], n, bottom_xyz[:2])]))


def _person(spec: PersonSpec) -> Asset:
    H, sh, hip = spec.height_m, spec.shoulder_m, spec.hip_m
    z_ankle, z_crotch, z_hip, z_waist = 0.05 * H, 0.47 * H, 0.53 * H, 0.60 * H
    z_sh, z_chin = 0.818 * H, 0.87 * H
    ly = hip / 4
    s = spec.stride_m
    legs = [_limb((0.0, y, z_crotch + 0.02), (x, y, z_ankle), 0.075, 0.05)
            for x, y in ((s, ly), (-s, -ly))]
    shoes = [g.box((x - 0.09, y - 0.05, 0.0), (x + 0.17, y + 0.05, z_ankle + 0.01))
             for x, y in ((s, ly), (-s, -ly))]
    pelvis = g.frustum(z_crotch - 0.02, z_waist, (0.11, hip / 2), (0.10, hip / 2 - 0.02))
    torso = g.convex_solid(np.concatenate([
        g.ring(0.10, hip / 2 - 0.02, z_waist - 0.03, 10), g.ring(0.12, sh / 2, z_sh - 0.05, 10),
        g.ring(0.09, sh / 2 - 0.05, z_sh + 0.01, 10)]))
    ay = sh / 2 - 0.03
    arms = [_limb((0.0, y, z_sh - 0.02), (-x * 0.8, y * 1.05, z_hip - 0.06), 0.055, 0.04)
            for x, y in ((s, ay), (-s, -ay))]
    hands = [g.ellipsoid((-x * 0.85, y * 1.05, z_hip - 0.1), (0.045, 0.035, 0.07), 4, 6)
             for x, y in ((s, ay), (-s, -ay))]
    neck = g.frustum(z_sh - 0.02, z_chin + 0.02, (0.05, 0.05), (0.045, 0.045), n=8)
    head_rz = (H - z_chin) / 2
    head = g.ellipsoid((0.01, 0.0, z_chin + head_rz), (0.10, 0.078, head_rz), 6, 10)
    hair = g.ellipsoid((-0.005, 0.0, z_chin + 1.25 * head_rz), (0.104, 0.082, 0.75 * head_rz), 5, 10)
    return finish_asset("pedestrian", spec.name, {
        spec.bottom: legs + [pelvis], "plastic_black": shoes, spec.top: [torso] + arms,
        spec.skin: hands + [neck, head], "hair_dark": [hair]})


# ---------------------------------------------------------------- buses and trucks
@dataclass(frozen=True)
class BusSpec:
    name: str
    length_m: float
    width_m: float
    height_m: float
    window_z_m: tuple[float, float]
    wheelbase_m: float
    front_overhang_m: float


BUS_SPECS: tuple[BusSpec, ...] = (
    BusSpec("bus_lowfloor_12m", 12.0, 2.55, 3.20, (1.05, 2.65), 5.9, 2.7),
    BusSpec("bus_coach_12m", 12.2, 2.55, 3.35, (1.55, 2.95), 6.2, 2.5),
)


def _side_windows(x0, x1, z0, z1, half_w, n_panes) -> list[g.Part]:
    """Window quads on both sides (outward-facing), n_panes along x with 0.12 m mullions."""
    xs = np.linspace(x0, x1, n_panes + 1)
    out = []
    for a, b in zip(xs[:-1], xs[1:]):
        a, b = a + 0.06, b - 0.06
        out.append(g.quads(np.array([[[a, -half_w, z0], [b, -half_w, z0], [b, -half_w, z1], [a, -half_w, z1]],
                                     [[b, half_w, z0], [a, half_w, z0], [a, half_w, z1], [b, half_w, z1]]])))
    return out


def _front_quad(x, y_half, z0, z1) -> g.Part:
    return g.quads(np.array([[[x, -y_half, z0], [x, y_half, z0], [x, y_half, z1], [x, -y_half, z1]]]))


def _back_quad(x, y_half, z0, z1) -> g.Part:
    return g.quads(np.array([[[x, y_half, z0], [x, -y_half, z0], [x, -y_half, z1], [x, y_half, z1]]]))


def _bus(spec: BusSpec) -> Asset:
    L, W, H = spec.length_m, spec.width_m, spec.height_m
    xf, xr = L / 2, -L / 2
    body = g.extrude_xz(np.array([[xr, 0.32], [xf - 0.05, 0.32], [xf, 0.45], [xf, H - 0.25],
                                  [xf - 0.25, H], [xr + 0.15, H], [xr, H - 0.15]]), -W / 2, W / 2)
    z0, z1 = spec.window_z_m
    hw = W / 2 + 0.005
    glass = _side_windows(xr + 0.5, xf - 1.3, z0, z1, hw, 8)
    glass.append(_front_quad(xf + 0.005, W / 2 - 0.12, 0.95, H - 0.35))
    glass.append(_back_quad(xr - 0.005, W / 2 - 0.2, z0 + 0.3, z1))
    r = 0.50
    xa = xf - spec.front_overhang_m
    wheels = [g.cylinder_y(r, s * (W / 2 - 0.32), s * (W / 2 - 0.01), (x, r), n=16)
              for x in (xa, xa - spec.wheelbase_m) for s in (-1, 1)]
    heads = [g.box((xf - 0.05, s * (W / 2 - 0.3) - 0.15, 0.55), (xf + 0.004, s * (W / 2 - 0.3) + 0.15, 0.72))
             for s in (-1, 1)]
    return finish_asset("bus", spec.name, {PAINT: [body], "glass_dark": glass, "rubber": wheels,
                                      "lens_clear": heads})


@dataclass(frozen=True)
class TruckSpec:
    name: str
    length_m: float
    width_m: float
    height_m: float
    cab_length_m: float
    cab_height_m: float


TRUCK_SPECS: tuple[TruckSpec, ...] = (
    TruckSpec("box_truck_7m", 7.4, 2.45, 3.40, 2.0, 2.70),
    TruckSpec("box_truck_8m", 8.4, 2.50, 3.50, 2.1, 2.85),
)


def _truck(spec: TruckSpec) -> Asset:
    L, W, H = spec.length_m, spec.width_m, spec.height_m
    xf, xr = L / 2, -L / 2
    xc = xf - spec.cab_length_m
    cab = g.extrude_xz(np.array([[xc, 0.45], [xf, 0.45], [xf, 1.6], [xf - 0.35, spec.cab_height_m],
                                 [xc, spec.cab_height_m]]), -(W / 2 - 0.05), W / 2 - 0.05)
    cargo = g.box((xr, -W / 2, 0.9), (xc - 0.1, W / 2, H))
    chassis = g.box((xr + 0.3, -0.5, 0.45), (xf - 0.2, 0.5, 0.9))
    glass = [_front_quad(xf + 0.005 - 0.35 * 0.05, W / 2 - 0.2, 1.65, spec.cab_height_m - 0.15)]
    glass += _side_windows(xc + 0.3, xf - 0.5, 1.55, spec.cab_height_m - 0.2, W / 2 - 0.045, 1)
    r = 0.46
    wheels = [g.cylinder_y(r, s * (W / 2 - 0.3), s * (W / 2 - 0.02), (x, r), n=16)
              for x in (xf - 1.2, xr + 1.5) for s in (-1, 1)]
    return finish_asset("truck", spec.name, {PAINT: [cab], "paint_white": [cargo],
                                        "metal_dark": [chassis], "glass_dark": glass,
                                        "rubber": wheels})


# ---------------------------------------------------------------- street furniture
TREE_VARIANTS = (("tree_round_small", 4.0, 1.7, 1.6), ("tree_round", 4.3, 2.2, 2.0),
                 ("tree_round_large", 4.6, 2.6, 2.4), ("tree_tall", 4.8, 1.8, 3.0),
                 ("tree_wide", 4.2, 2.7, 1.8), ("tree_young", 4.0, 1.4, 1.5))
TREE_CANOPY_BOTTOM_M = 3.7   # above the tallest vehicle (3.5 m), so canopies may overhang lanes


def _tree(name: str, trunk_m: float, canopy_r_m: float, canopy_rz_m: float) -> Asset:
    trunk = g.frustum(0.0, trunk_m + 0.5, (0.17, 0.17), (0.10, 0.10), n=10)
    bottom = max(TREE_CANOPY_BOTTOM_M, trunk_m - 0.3)
    canopy = [g.ellipsoid((0.0, 0.0, bottom + canopy_rz_m), (canopy_r_m, canopy_r_m, canopy_rz_m), 6, 12),
              g.ellipsoid((0.25 * canopy_r_m, -0.2 * canopy_r_m, bottom + 1.45 * canopy_rz_m),
                          (0.65 * canopy_r_m, 0.65 * canopy_r_m, 0.6 * canopy_rz_m), 5, 10)]
    return finish_asset("tree", name, {"bark": [trunk], "leaves": canopy})


LAMP_VARIANTS = (("lamp_arm_8m", 8.0, 1.8), ("lamp_arm_6m", 6.0, 1.2))


def _lamp(name: str, pole_m: float, arm_m: float) -> Asset:
    pole = g.frustum(0.0, pole_m, (0.10, 0.10), (0.06, 0.06), n=10)
    base = g.frustum(0.0, 0.6, (0.16, 0.16), (0.13, 0.13), n=10)
    arm = g.box((0.0, -0.04, pole_m - 0.25), (arm_m, 0.04, pole_m - 0.17))
    head = g.box((arm_m - 0.25, -0.16, pole_m - 0.38), (arm_m + 0.35, 0.16, pole_m - 0.18))
    lens = g.quads(np.array([[[arm_m - 0.2, -0.12, pole_m - 0.385], [arm_m - 0.2, 0.12, pole_m - 0.385],
                              [arm_m + 0.3, 0.12, pole_m - 0.385], [arm_m + 0.3, -0.12, pole_m - 0.385]]]))
    return finish_asset("lamp", name, {"metal_galvanized": [pole, arm], "metal_dark": [base, head],
                                  "lens_clear": [lens]}, centre_xy=False)   # origin at the pole


BENCH_VARIANTS = (("bench_backrest", True), ("bench_flat", False))


def _bench(name: str, backrest: bool) -> Asset:
    seat = g.box((-0.25, -0.9, 0.42), (0.25, 0.9, 0.47))
    legs = [g.box((-0.22, y - 0.03, 0.0), (0.22, y + 0.03, 0.42)) for y in (-0.75, 0.75)]
    wood = [seat]
    if backrest:
        wood.append(g.box((-0.28, -0.9, 0.55), (-0.24, 0.9, 0.85)))
        legs += [g.box((-0.26, y - 0.03, 0.42), (-0.23, y + 0.03, 0.85)) for y in (-0.75, 0.75)]
    return finish_asset("bench", name, {"wood": wood, "metal_dark": legs})


MAILBOX_VARIANTS = (("mailbox_collection", "mailbox_blue"), ("mailbox_pillar", "paint_red"))


def _mailbox(name: str, paint: str) -> Asset:
    if name == "mailbox_pillar":
        body = [g.frustum(0.0, 1.35, (0.24, 0.24), (0.24, 0.24), n=14),
                g.ellipsoid((0.0, 0.0, 1.35), (0.27, 0.27, 0.18), 4, 14)]
        slot = g.box((0.20, -0.12, 1.12), (0.245, 0.12, 1.16))
        return finish_asset("mailbox", name, {paint: body, "plastic_black": [slot]})
    legs = [g.box((x - 0.03, y - 0.03, 0.0), (x + 0.03, y + 0.03, 0.12))
            for x in (-0.2, 0.2) for y in (-0.22, 0.22)]
    t = np.linspace(0, np.pi, 9)
    top = g.extrude_xz(np.stack([0.25 * np.cos(t), 1.05 + 0.2 * np.sin(t)], -1), -0.26, 0.26)
    body = g.box((-0.25, -0.26, 0.12), (0.25, 0.26, 1.06))
    return finish_asset("mailbox", name, {paint: [body, top], "metal_dark": legs})
