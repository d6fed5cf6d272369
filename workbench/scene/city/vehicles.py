"""Detailed vehicles (CityRecipe.asset_detail 'detailed'): the cues a detector learns from.

Cars (the 13 CarSpec body shapes: sedans, coupé, hatchbacks, wagon, SUVs, crossover, minivan,
pickup with an open bed, van), buses and box trucks get tyres (rubber) with rims and hubs
(metal), wheel arches cut into the body with wheel-well liners behind the tyres, a closed glass
cabin (cars) or window panes (buses, trucks), head-lights (`lens_clear`) and tail-lights
(`lens_red`) — night lighting (render/lamps.py) finds its lamps from these meshes —, side
mirrors, plastic bumpers, licence plates and a body rounded by chamfered extrusion. Every part
is a closed, outward-wound convex solid; parts are merged per material as in assets.py.

Facts used: dipped-beam head-lamps 0.50–1.20 m and rear position lamps 0.35–1.50 m above the
ground (UN ECE Regulation 48, §6.2.4 and §6.10.4); EU licence plates 520 × 110 mm, UK rear
plates yellow (BS AU 145e); spec-sheet widths exclude mirrors, so the body matches the CarSpec
width and the mirrors add ~0.1 m a side (car) or ~0.2 m (bus, truck) to the bounding box.
"""
from __future__ import annotations

import numpy as np

from workbench.scene.city import geometry as g
from workbench.scene.city.assets import (BUS_SPECS, CAR_SPECS, PAINT, TRUCK_SPECS, Asset, BusSpec, CarSpec,
                                         TruckSpec, finish_asset)

PLATE_W_M, PLATE_H_M = 0.52, 0.11        # EU licence plate
ROUND_M = 0.07                           # chamfer of body edges (the "rounded" body)
HEADLAMP_MIN_Z_M = 0.50                  # ECE R48 lower edge of dipped-beam head-lamps


def _clip(poly: np.ndarray, normal: tuple[float, float], offset: float) -> np.ndarray:
    """Convex polygon (K×2) ∩ half-plane {p : normal·p ≤ offset} (Sutherland–Hodgman)."""
    n = np.asarray(normal, float)
    out = []
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        da, db = a @ n - offset, b @ n - offset
        if da <= 0:
            out.append(a)
        if (da < 0 < db) or (db < 0 < da):
            out.append(a + (b - a) * (da / (da - db)))
    return np.array(out).reshape(-1, 2)


def _box2(poly: np.ndarray, x0=-np.inf, x1=np.inf, z0=-np.inf, z1=np.inf) -> np.ndarray:
    """Clip a convex xz polygon to x0 ≤ x ≤ x1, z0 ≤ z ≤ z1."""
    for n, o in (((1, 0), x1), ((-1, 0), -x0), ((0, 1), z1), ((0, -1), -z0)):
        if np.isfinite(o):
            poly = _clip(poly, n, o)
    return poly


def _slab(poly: np.ndarray, half_w: float, outer: np.ndarray | None = None,
          round_m: float = ROUND_M) -> g.Part:
    """A convex xz polygon extruded across ±half_w; with `outer` (the polygon trimmed at its
    rounded edges) the full polygon stops round_m inside the sides and `outer` reaches them:
    the convex hull chamfers the edges between."""
    def at(p, y):
        return np.stack([p[:, 0], np.full(len(p), y), p[:, 1]], -1)
    if outer is None:
        return g.convex_solid(np.concatenate([at(poly, -half_w), at(poly, half_w)]))
    w = half_w - round_m
    return g.convex_solid(np.concatenate([at(poly, -w), at(poly, w), at(outer, -half_w), at(outer, half_w)]))


def _upper_body(profile: np.ndarray, half_w: float, split_z: float) -> g.Part:
    """The body above split_z: one slab rounded at its ends and along its top edges."""
    x_lo, x_hi, z_top = profile[:, 0].min(), profile[:, 0].max(), profile[:, 1].max()
    r = ROUND_M
    return _slab(_box2(profile, z0=split_z), half_w, _box2(profile, x_lo + r, x_hi - r, split_z, z_top - r))


def _lower_body(profile: np.ndarray, half_w: float, wheels_x: list[float], wheel_z: float,
                arch_r: float, split_z: float) -> list[g.Part]:
    """The body below split_z with semicircular wheel arches of radius arch_r around the wheel
    centres (x, wheel_z): blocks between the arches (the front and rear ones rounded in plan)
    and 6 strips over each arch."""
    lower = _box2(profile, z1=split_z)
    x_lo, x_hi = lower[:, 0].min(), lower[:, 0].max()
    cuts = sorted((x - arch_r, x + arch_r) for x in wheels_x)
    edges = [x_lo] + [c for pair in cuts for c in pair] + [x_hi]
    parts = []
    for i, (a, b) in enumerate(zip(edges[::2], edges[1::2])):
        block = _box2(lower, a, b)
        outer = _box2(block, x0=a + ROUND_M) if i == 0 else _box2(block, x1=b - ROUND_M) if i == len(cuts) else None
        parts.append(_slab(block, half_w, outer))
    t = np.linspace(0.0, np.pi, 7)
    normals, offsets = _halfplanes(lower)
    for x in wheels_x:
        arc = np.stack([x + arch_r * np.cos(t), wheel_z + arch_r * np.sin(t)], -1)
        for p, q in zip(arc[:-1], arc[1:]):
            strip = np.array([p, q, [q[0], split_z], [p[0], split_z]])
            for n, o in zip(normals, offsets):
                strip = _clip(strip, n, o)
            if len(strip) >= 3 and _area(strip) > 1e-4:
                parts.append(_slab(strip, half_w))
    return parts


def _area(poly: np.ndarray) -> float:
    x, z = poly[:, 0], poly[:, 1]
    return float(abs(np.dot(x, np.roll(z, -1)) - np.dot(z, np.roll(x, -1))) / 2)


def _halfplanes(poly: np.ndarray):
    """Outward edge normals and offsets of a counter-clockwise convex polygon."""
    e = np.roll(poly, -1, axis=0) - poly
    if (e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0]).sum() < 0:     # clockwise: flip the normals
        e = -e
    n = np.stack([e[:, 1], -e[:, 0]], -1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return list(n), list(np.einsum("ij,ij->i", n, poly))


def _wheel(x: float, r: float, y_out: float, width: float, side: int, n: int = 16) -> dict[str, list[g.Part]]:
    """Tyre (rubber) whose outer face is at |y| = y_out, an alloy rim proud of it and a hub cap."""
    s = side
    tyre = g.cylinder_y(r, s * (y_out - width), s * y_out, (x, r), n=n)
    rim = g.cylinder_y(0.62 * r, s * (y_out - 0.03), s * (y_out + 0.006), (x, r), n=n)
    hub = g.cylinder_y(0.16 * r, s * (y_out - 0.01), s * (y_out + 0.02), (x, r), n=8)
    return {"rubber": [tyre], "metal_galvanized": [rim, hub]}


def _add(parts: dict[str, list[g.Part]], more: dict[str, list[g.Part]]) -> None:
    for k, v in more.items():
        parts.setdefault(k, []).extend(v)


def _mirrors(x: float, z: float, half_w: float, reach: float, size: tuple[float, float, float]
             ) -> list[g.Part]:
    """Door mirrors: a housing tapering toward the body, reaching `reach` past each side."""
    lx, ly, lz = size
    out = []
    for s in (-1, 1):
        y0, y1 = s * (half_w - 0.04), s * (half_w + reach)
        out.append(g.convex_solid(np.array([
            [x - 0.3 * lx, y0, z + 0.3 * lz], [x + 0.3 * lx, y0, z + 0.3 * lz], [x - 0.3 * lx, y0, z + 0.7 * lz],
            [x + 0.3 * lx, y0, z + 0.7 * lz],
            [x - lx / 2, y1 - s * ly, z], [x + lx / 2, y1 - s * ly, z], [x - lx / 2, y1 - s * ly, z + lz],
            [x + lx / 2, y1 - s * ly, z + lz],
            [x - lx / 2, y1, z + 0.05 * lz], [x + lx / 3, y1, z + 0.05 * lz], [x - lx / 2, y1, z + 0.95 * lz],
            [x + lx / 3, y1, z + 0.95 * lz]])))
    return out


def _plate(x_face: float, z_mid: float, facing: int) -> g.Part:
    """A licence plate 12 mm thick whose face is at x_face, facing ±x."""
    return g.box((x_face - 0.012 if facing > 0 else x_face, -PLATE_W_M / 2, z_mid - PLATE_H_M / 2),
                 (x_face if facing > 0 else x_face + 0.012, PLATE_W_M / 2, z_mid + PLATE_H_M / 2))


def _lamp_pair(x0: float, x1: float, y_mid: float, half_y: float, z0: float, z1: float) -> list[g.Part]:
    return [g.box((x0, s * y_mid - half_y, z0), (x1, s * y_mid + half_y, z1)) for s in (-1, 1)]


# ---------------------------------------------------------------- cars
def detailed_car(spec: CarSpec, rear_plate: str = "plate_white") -> Asset:
    """A detailed car of the CarSpec's dimensions (module docstring); `rear_plate` its colour."""
    L, W, H = spec.length_m, spec.width_m, spec.height_m
    c, belt, r = spec.clearance_m, spec.belt_m, spec.wheel_r_m
    xf, xr = L / 2, -L / 2
    bf, br = xf - 0.05, xr + 0.04                       # body ends (bumpers reach xf, xr)
    nose = max(c + 0.6 * (belt - c), HEADLAMP_MIN_Z_M + 0.16)
    pickup = spec.rear_m > 1.0
    profile = np.array([[br + 0.10, c], [bf - 0.15, c], [bf, c + 0.12], [bf, nose],
                        [bf - 0.25, belt - 0.10], [xf - spec.hood_m, belt],
                        [xr + spec.rear_m, belt], [br, belt - 0.08], [br, c + 0.10]])
    arch_r = r + 0.05
    wheels_x = [spec.wheelbase_m / 2 - 0.05, -spec.wheelbase_m / 2 - 0.05]
    split = r + arch_r + 0.03
    parts: dict[str, list[g.Part]] = {PAINT: [], "plastic_black": [], "metal_galvanized": [], "rubber": []}
    parts[PAINT] += _lower_body(profile, W / 2, wheels_x, r, arch_r, split)
    if pickup:      # cab and bonnet over the front, an open bed behind
        x_bed = xr + spec.rear_m
        parts[PAINT].append(_upper_body(_box2(profile, x0=x_bed), W / 2, split))
        floor = split + 0.08
        parts[PAINT] += [g.box((br, -W / 2, split), (x_bed, W / 2, floor)),
                         g.box((br, -W / 2, floor), (x_bed, -W / 2 + 0.05, belt)),
                         g.box((br, W / 2 - 0.05, floor), (x_bed, W / 2, belt)),
                         g.box((br, -W / 2 + 0.05, floor), (br + 0.05, W / 2 - 0.05, belt - 0.02))]
    else:
        parts[PAINT].append(_upper_body(profile, W / 2, split))
    # wheel-well liners behind the tyres, so no arch can be seen through
    parts["plastic_black"] += [g.box((x - arch_r, -(W / 2 - 0.24), c + 0.02), (x + arch_r, W / 2 - 0.24, split))
                               for x in wheels_x]
    for x in wheels_x:
        for s in (-1, 1):
            _add(parts, _wheel(x, r, W / 2 - 0.025, 0.20, s))
    # glass cabin and roof
    x_ws, x_rw = xf - spec.hood_m, xr + spec.rear_m
    x_rf, x_rr = x_ws - spec.screen_run_m, x_rw + spec.back_run_m
    top = H - 0.06
    gw = W / 2 - ROUND_M - 0.01
    parts["glass_dark"] = [g.convex_solid(np.array([
        [x_rw, -gw, belt], [x_ws, -gw, belt], [x_ws, gw, belt], [x_rw, gw, belt],
        [x_rr, -(W / 2 - 0.17), top], [x_rf, -(W / 2 - 0.17), top],
        [x_rf, W / 2 - 0.17, top], [x_rr, W / 2 - 0.17, top]]))]
    rw = W / 2 - 0.19
    parts[PAINT].append(g.convex_solid(np.array([
        [x_rr + 0.02, -rw, top - 0.02], [x_rf - 0.02, -rw, top - 0.02], [x_rf - 0.02, rw, top - 0.02],
        [x_rr + 0.02, rw, top - 0.02], [x_rr + 0.06, -(rw - 0.04), H], [x_rf - 0.06, -(rw - 0.04), H],
        [x_rf - 0.06, rw - 0.04, H], [x_rr + 0.06, rw - 0.04, H]])))
    # seats seen through the glass: front and rear rows with their backrests
    x_mid = (x_ws + x_rw) / 2
    seat_z = belt + 0.30
    parts["plastic_black"] += [g.box((x_mid + 0.05, -(W / 2 - 0.30), belt - 0.2), (x_mid + 0.25, W / 2 - 0.30, seat_z)),
                               g.box((x_rw + 0.15, -(W / 2 - 0.30), belt - 0.2),
                                     (min(x_rw + 0.35, x_mid - 0.2), W / 2 - 0.30, seat_z))]
    # bumpers, lights, plates, mirrors
    bz0, bz1 = c + 0.04, c + 0.28
    parts["plastic_black"] += [
        g.convex_solid(np.array([[x, s * y, z] for s in (-1, 1) for z in (bz0, bz1)
                                 for x, y in ((xf - 0.006, W / 2 - 0.14), (bf - 0.12, W / 2 - 0.02))])),
        g.convex_solid(np.array([[x, s * y, z] for s in (-1, 1) for z in (bz0, bz1)
                                 for x, y in ((xr, W / 2 - 0.14), (br + 0.12, W / 2 - 0.02))]))]
    parts["lens_clear"] = _lamp_pair(bf - 0.20, bf + 0.01, W / 2 - 0.30, 0.16, nose - 0.14, nose - 0.03)
    tail_z = max(belt - 0.25, 0.40)
    parts["lens_red"] = _lamp_pair(br - 0.01, br + 0.15, W / 2 - 0.22, 0.13, tail_z, tail_z + 0.12)
    parts["plate_white"] = [_plate(xf, (bz0 + bz1) / 2, +1)]
    parts.setdefault(rear_plate, []).append(_plate(br - 0.012, tail_z - 0.10, -1))
    parts["plastic_black"] += _mirrors(x_ws - 0.12, belt + 0.03, W / 2, 0.11, (0.12, 0.05, 0.14))
    return finish_asset("car", spec.name, parts)


# ---------------------------------------------------------------- buses and trucks
def _panes(x0: float, x1: float, z0: float, z1: float, half_w: float, n_panes: int) -> list[g.Part]:
    """Window panes on both sides, n along x with 0.12 m mullions: outward-facing quads."""
    xs = np.linspace(x0, x1, n_panes + 1)
    out = []
    for a, b in zip(xs[:-1] + 0.06, xs[1:] - 0.06):
        out.append(g.quads(np.array([[[a, -half_w, z0], [b, -half_w, z0], [b, -half_w, z1], [a, -half_w, z1]],
                                     [[b, half_w, z0], [a, half_w, z0], [a, half_w, z1], [b, half_w, z1]]])))
    return out


def detailed_bus(spec: BusSpec) -> Asset:
    """A detailed city bus / coach of the BusSpec's dimensions."""
    L, W, H = spec.length_m, spec.width_m, spec.height_m
    xf, xr = L / 2, -L / 2
    bf, br = xf - 0.06, xr + 0.06
    floor, r = 0.32, 0.50
    profile = np.array([[br, floor], [bf - 0.05, floor], [bf, floor + 0.13], [bf, H - 0.25],
                        [bf - 0.25, H], [br + 0.15, H], [br, H - 0.15]])
    xa = xf - spec.front_overhang_m
    wheels_x = [xa, xa - spec.wheelbase_m]
    arch_r = r + 0.06
    split = r + arch_r + 0.04
    parts: dict[str, list[g.Part]] = {PAINT: [_upper_body(profile, W / 2, split),
                                              *_lower_body(profile, W / 2, wheels_x, r, arch_r, split)],
                                      "plastic_black": [], "metal_galvanized": [], "rubber": []}
    parts["plastic_black"] += [g.box((x - arch_r, -(W / 2 - 0.36), floor + 0.02), (x + arch_r, W / 2 - 0.36, split))
                               for x in wheels_x]
    for x in wheels_x:
        for s in (-1, 1):
            _add(parts, _wheel(x, r, W / 2 - 0.03, 0.30, s, n=18))
    z0, z1 = spec.window_z_m
    hw = W / 2 + 0.005
    glass = _panes(br + 0.5, bf - 1.3, z0, z1, hw, 8)
    glass.append(g.quads(np.array([[[bf + 0.004, -(W / 2 - 0.12), 0.95], [bf + 0.004, W / 2 - 0.12, 0.95],
                                    [bf + 0.004, W / 2 - 0.12, H - 0.35], [bf + 0.004, -(W / 2 - 0.12), H - 0.35]]])))
    glass.append(g.quads(np.array([[[br - 0.004, W / 2 - 0.2, z0 + 0.3], [br - 0.004, -(W / 2 - 0.2), z0 + 0.3],
                                    [br - 0.004, -(W / 2 - 0.2), z1], [br - 0.004, W / 2 - 0.2, z1]]])))
    parts["glass_dark"] = glass
    parts["plastic_black"] += [g.box((bf - 0.15, -(W / 2 - 0.03), floor + 0.05), (xf, W / 2 - 0.03, floor + 0.40)),
                               g.box((xr, -(W / 2 - 0.03), floor + 0.05), (br + 0.15, W / 2 - 0.03, floor + 0.40))]
    parts["plastic_black"] += _mirrors(bf - 0.35, 1.95, W / 2, 0.22, (0.12, 0.06, 0.35))
    parts["lens_clear"] = _lamp_pair(bf - 0.05, bf + 0.012, W / 2 - 0.30, 0.15, 0.80, 0.94)
    parts["lens_red"] = _lamp_pair(br - 0.012, br + 0.05, W / 2 - 0.18, 0.08, 0.80, 1.20)
    parts["plate_white"] = [_plate(xf + 0.006, floor + 0.22, +1), _plate(br - 0.012, 1.05, -1)]
    return finish_asset("bus", spec.name, parts)


def detailed_truck(spec: TruckSpec) -> Asset:
    """A detailed box truck of the TruckSpec's dimensions: cab with arches, cargo box, chassis."""
    L, W, H = spec.length_m, spec.width_m, spec.height_m
    xf, xr = L / 2, -L / 2
    xc = xf - spec.cab_length_m
    bf = xf - 0.06
    r = 0.46
    xa, xb = xf - 1.2, xr + 1.5
    arch_r = r + 0.06
    split = r + arch_r + 0.04
    cab_w = W / 2 - 0.05
    profile = np.array([[xc, 0.45], [bf, 0.45], [bf, 1.6], [bf - 0.35, spec.cab_height_m], [xc, spec.cab_height_m]])
    parts: dict[str, list[g.Part]] = {PAINT: [_upper_body(profile, cab_w, split),
                                              *_lower_body(profile, cab_w, [xa], r, arch_r, split)],
                                      "paint_white": [g.box((xr + 0.02, -W / 2, 0.95), (xc - 0.1, W / 2, H))],
                                      "metal_dark": [g.box((xr + 0.3, -0.5, 0.45), (xf - 0.2, 0.5, 0.95)),
                                                     g.box((xr + 0.02, -(W / 2 - 0.1), 0.40),
                                                           (xr + 0.12, W / 2 - 0.1, 0.55))],   # underrun guard
                                      "plastic_black": [], "metal_galvanized": [], "rubber": []}
    parts["plastic_black"].append(g.box((xa - arch_r, -(cab_w - 0.34), 0.47), (xa + arch_r, cab_w - 0.34, split)))
    for x in (xa, xb):
        for s in (-1, 1):
            _add(parts, _wheel(x, r, W / 2 - 0.04, 0.28, s, n=18))
    zc = spec.cab_height_m
    glass = [g.quads(np.array([[[bf + 0.004 - 0.35 * 0.05, -(cab_w - 0.15), 1.65],
                                [bf + 0.004 - 0.35 * 0.05, cab_w - 0.15, 1.65],
                                [bf + 0.004 - 0.35 * 0.05, cab_w - 0.15, zc - 0.15],
                                [bf + 0.004 - 0.35 * 0.05, -(cab_w - 0.15), zc - 0.15]]]))]
    glass += _panes(xc + 0.3, bf - 0.5, 1.55, zc - 0.2, cab_w + 0.005, 1)
    parts["glass_dark"] = glass
    parts["plastic_black"].append(g.box((bf - 0.15, -(cab_w - 0.02), 0.50), (xf - 0.006, cab_w - 0.02, 0.85)))
    parts["plastic_black"] += _mirrors(bf - 0.3, 1.85, cab_w, 0.25, (0.10, 0.06, 0.32))
    parts["lens_clear"] = _lamp_pair(bf - 0.05, bf + 0.01, cab_w - 0.30, 0.15, 0.95, 1.10)
    parts["lens_red"] = _lamp_pair(xr + 0.005, xr + 0.05, W / 2 - 0.25, 0.10, 0.98, 1.18)
    parts["plate_white"] = [_plate(xf, 0.68, +1)]
    parts["plate_yellow"] = [_plate(xr + 0.02, 0.475, -1)]
    return finish_asset("truck", spec.name, parts)


def detailed_builders() -> dict[str, dict[str, tuple]]:
    """{class: {variant: (builder, *args)}} for catalog.DETAILED_BUILDERS (same variant names as
    the simple assets; every third car has a yellow rear plate)."""
    return {"car": {s.name: (detailed_car, s, "plate_yellow" if i % 3 == 2 else "plate_white")
                    for i, s in enumerate(CAR_SPECS)},
            "bus": {s.name: (detailed_bus, s) for s in BUS_SPECS},
            "truck": {s.name: (detailed_truck, s) for s in TRUCK_SPECS}}
