"""Many spot lamps as one Mitsuba emitter that picks, for each next-event sample, a lamp by its
light at the shading point (NightParams.light_selection 'shading').

Mitsuba 3 picks the emitter for next-event estimation (NEE) from one global table
(`sampling_weight`), the same at every point. In a city at night a point lit almost only by the
lamp 3 m away then finds that lamp once in tens of samples, and the rare sample that does find it
is weighted by 1/p, so the point is a firefly: at night the fireflies are the one-bounce indirect
light (render.max_depth 2 has none) of surfaces lit by a lamp whose global share is small. This
emitter holds all the lamps (`spot_emitter` dicts) and samples lamp k with probability

    p_k(x) = w_k(x) / Σ_j w_j(x),   w_k(x) = I_k(λ) · g_k(x) · max(cos θ_x + COS_FLOOR, BACK_FLOOR) / r_k²,

I_k(λ) the lamp's on-axis radiant intensity (W/sr/nm) summed over the path's wavelengths (a camera
that sees red and near-infrared, RCCC without an IR cut, takes a red tail-light's 625 nm or a sodium
lamp's 819 nm line where the brighter white head-lights give nothing: weighed by luminous
intensity, a tail-light 18 m from a façade in city_night frame 0 was picked with p = 2.7e-4 and its
625 nm samples were worth ~1,600× the point's mean), g_k a cone factor (1 inside the beam, falling linearly in
cos θ to 0 at the cut-off: zero exactly where the lamp sheds no light) times, for a spot with a
projection texture (the low-beam head-lights, render/low_beam.py), the texture max-pooled onto a
coarse grid (render/spot_pattern.py: a bound of the texture near the direction), r_k the distance
and θ_x the angle at the receiver between its geometric normal and the lamp: a lamp's share
follows its unshadowed direct light at x, as a light tree does in PBRT-v4. The city's surfaces are
opaque and their normals face out (no camera ray and 0.2–0.5 % of bounced rays of city_night
frames 0–2 met a back face), so a lamp behind the surface (the street lamp on a building's other
side) takes only BACK_FLOOR: weighed by |cos θ| it took 88 % of the samples at a façade point in
city_night frame 0, the two head-lights 94 m away that light it 0.6 %, and at 550 nm their samples
were worth ~90× the point's mean. COS_FLOOR keeps a lamp at grazing incidence sampled.

Scoring every lamp at every sample cost a night frame 2.7× a day frame's time per sample (a dense
night city has ~250 lights: 60 cars' head- and tail-lights and the street lamps). The weights
are therefore taken only over the CANDIDATES lamps of x's cell in a horizontal grid (CELL_M
cells over the lamps' extent) and of the side its normal faces (±x, ±y, ±z: a lamp behind the whole
cell on that side takes BACK_FLOOR), those whose share of a bound of w_k over the cell, in any
40-nm band, is largest (over the cell's
column as cubes: the nearest distance to each, the cone at the axis's smallest angle to it, a
texture's coarse grid dilated over the cube's angular radius; in each band the lamp's mean
intensity there), and
a share ε = GLOBAL_SHARE of the samples comes from a table t of all lamps, half alike, half by flux Φ_k
(its sampling_weight, lm: a low beam's flux, or peak × cone solid angle for a plain spot):

    p_k(x) = (1 − ε) w_k(x) / Σ_{j in cell} w_j(x) · [k in cell] + ε t_k,   t_k = ½/N + ½ Φ_k / Σ_j Φ_j,

(ε = 1 where no candidate lights x). The even half is for dim lamps that alone light a point the
cell's bright candidates miss (a tail-light on a dark façade behind a queue of head-lights: by
flux alone 1e-4 of the samples, and city_night's dark façades sparkled). Every lamp keeps a
positive probability everywhere, so a lamp the grid leaves out costs variance, never bias; the cost per sample no longer grows with
the number of lamps (city_detection_night_rccc, 320×240: 0.33 → 0.17 core-s per sample per
frame, a day frame 0.10). The value returned is the Mitsuba `spot` emitter's own (intensity ×
the spot's angular falloff × its texture at Mitsuba's uv / r²) divided by p_k, so the expected image is that of the separate
spots; only the noise changes. Once the scene is loaded, render/lamp_set_cache.py re-ranks each
cell-side's candidates for the camera by the lamps' visible light at the points of a pre-pass, and
weighs each slot (the `valid` factor) by the lamp's visible fraction there: the bound alone is
blind to occlusion and to where the cell's surfaces are. Lamps are point sources (delta position):
BSDF sampling never hits them, so no MIS weight is needed.
"""
from __future__ import annotations

import hashlib

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render import spot_pattern

PLUGIN = "lamp_set"
COS_FLOOR = 0.05
SHAPE_WL0_NM, SHAPE_WL_COUNT = 300.0, 801     # the spectral shapes on a 1-nm grid, 300–1100 nm, for the weights
SIDES = ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0))   # receiving normal: axis, sign
SHAPE_BANDS_NM = tuple((a, a + 40.0) for a in np.arange(360.0, 1040.0, 40.0))   # the grid ranks lamps per band
BACK_FLOOR = 1e-3          # weight factor of a lamp behind the receiving surface (it can light it only through it)
CELL_M = 8.0               # the candidate grid's cells (m)
GRID_MARGIN_M = 40.0       # the grid reaches this far past the outermost lamps; points beyond use its edge cells
CANDIDATES = 16            # lamps per cell weighed exactly at the shading point
GLOBAL_SHARE = 0.05        # share of samples from the table of all lamps (global_table): every lamp possible everywhere
UNIFORM_SHARE = 0.5        # of the global share, spread evenly over the lamps (the rest by flux)
R_MIN_M = 1.0              # nearest distance the cell bound assumes
RECEIVER_TOP_M = 64.0      # the cone test covers shading points up to this height (higher: the global share)
_SETS: dict[str, dict] = {}        # set key → lamp arrays and spectra (read while its scene loads)
MAX_SETS = 64
_REGISTERED: set[str] = set()


def _spot_arrays(spots: dict) -> dict:
    """Per-lamp arrays from spot_emitter dicts: position (m), frame (left, up, axis), cone (cosines;
    cut-off in rad, 1/(cut-off − beam) in 1/rad, tan of the cut-off), the distinct spectral shapes
    (max 1; also on a 1-nm grid, shape_table) with each lamp's index into them and scale (W/sr/nm
    at the shape's maximum), and the distinct projection textures with each lamp's slot (0: none; slot s > 0 is
    textures[s − 1]) and their coarse tables (spot_pattern.coarse_tables; slot 0 all ones)."""
    pos, left, up, axis, cos_cut, cos_beam, cut, inv_tw, kind, scale, slot = ([] for _ in range(11))
    shapes: dict[bytes, int] = {}
    spectra, textures = [], []
    for name, e in spots.items():
        if e.get("type") != "spot":
            raise InvalidValueError(f"lamp set: emitter '{name}' is a {e.get('type')!r}, only 'spot' lamps can join")
        p, lf, u, a = spot_pattern.frame(e)
        c_deg, b_deg = float(e["cutoff_angle"]), float(e["beam_width"])
        wl, v = (np.array(x, dtype=np.float64) for x in zip(*e["intensity"]["value"]))
        s = float(v.max())
        if not s > 0:
            raise InvalidValueError(f"lamp set: emitter '{name}' has no positive intensity")
        key = hashlib.sha1(np.r_[wl, np.round(v / s, 12)].tobytes()).digest()
        if key not in shapes:
            shapes[key] = len(spectra)
            spectra.append({"type": "spectrum", "value": list(zip(wl.tolist(), (v / s).tolist()))})
        tex = e.get("texture")
        if tex is not None and not any(t is tex for t in textures):
            textures.append(tex)
        pos.append(p)
        left.append(lf)
        up.append(u)
        axis.append(a)
        cos_cut.append(np.cos(np.radians(c_deg)))
        cos_beam.append(np.cos(np.radians(b_deg)))
        cut.append(np.radians(c_deg))
        inv_tw.append(1.0 / np.radians(c_deg - b_deg))
        kind.append(shapes[key])
        scale.append(s)
        slot.append(0 if tex is None else 1 + next(i for i, t in enumerate(textures) if t is tex))
    cut_deg = {sl: float(np.degrees(c)) for sl, c in zip(slot, cut) if sl}
    table_wl = SHAPE_WL0_NM + np.arange(SHAPE_WL_COUNT)
    shape_table = np.concatenate([np.interp(table_wl, *(np.array(x, dtype=np.float64) for x in zip(*d["value"])),
                                            left=0.0, right=0.0) for d in spectra])
    pyramids = [np.ones((1, spot_pattern.COARSE_TEXELS, spot_pattern.COARSE_TEXELS))]
    pyramids += [spot_pattern.coarse_tables(spot_pattern.texture_data(t)) for t in textures]
    arrays = {"pos": np.array(pos), "left": np.array(left), "up": np.array(up), "axis": np.array(axis),
              "cos_cut": np.array(cos_cut), "cos_beam": np.array(cos_beam), "cut": np.array(cut),
              "inv_tw": np.array(inv_tw), "uv_factor": np.tan(np.array(cut)),
              "kind": np.array(kind), "scale": np.array(scale), "slot": np.array(slot), "spectra": spectra,
              "textures": textures, "pyramids": pyramids, "texture_cut_deg": cut_deg, "shape_table": shape_table}
    arrays["flux"] = np.array([float(e["sampling_weight"]) for e in spots.values()])   # lm (a bound for a plain spot)
    arrays["grid"] = _candidate_grid(arrays)
    return arrays


def _candidate_grid(arrays: dict) -> dict:
    """The grid of candidate lamps (module docstring): origin (m), cell size, cells along x and y,
    and per cell CANDIDATES lamp indices with a 0/1 flag (a slot past the lamps that can light the
    cell is flagged 0), ranked by their largest share, over SHAPE_BANDS_NM, of the bound of the
    lamps' light in the cell: a red tail-light that dominates a façade's 600–640 nm is a candidate
    beside the white lamps that dominate the rest."""
    pos, axis, cos_cut = arrays["pos"], arrays["axis"], arrays["cos_cut"]
    lo = pos[:, :2].min(0) - GRID_MARGIN_M
    n = np.maximum(np.ceil((pos[:, :2].max(0) + GRID_MARGIN_M - lo) / CELL_M).astype(int), 1)
    cx = lo[0] + (np.arange(n[0]) + 0.5) * CELL_M
    cy = lo[1] + (np.arange(n[1]) + 0.5) * CELL_M
    centre = np.stack(np.meshgrid(cx, cy, indexing="xy"), -1).reshape(-1, 2)          # cell y-major, then x
    half = 0.5 * CELL_M
    gap_xy = np.maximum(np.abs(pos[None, :, :2] - centre[:, None, :]) - half, 0.0)     # cells × lamps × 2
    cut, beam = np.arccos(cos_cut), np.arccos(arrays["cos_beam"])
    # the bound over the cell's column up to RECEIVER_TOP_M, as cubes of CELL_M: the nearest
    # distance to the cube, and the cone at the axis's smallest angle to it (the angle to its
    # centre less its angular radius, arcsin R/d of its bounding sphere; 0 with the lamp inside)
    radius = half * np.sqrt(3.0)
    # per receiving side (normal ±x, ±y, ±z): a lamp behind every point of the cube on that side
    # lights it only through the surface (BACK_FLOOR)
    bound = np.zeros((len(SIDES),) + gap_xy.shape[:2])
    for zc in np.arange(half, RECEIVER_TOP_M, CELL_M):
        gap_z = np.maximum(np.abs(pos[:, 2] - zc) - half, 0.0)
        r2 = np.maximum((gap_xy ** 2).sum(-1) + gap_z[None] ** 2, R_MIN_M ** 2)
        v = np.concatenate([centre[:, None, :] - pos[None, :, :2],
                            np.broadcast_to((zc - pos[:, 2])[None, :, None], r2.shape + (1,))], -1)
        dist = np.linalg.norm(v, axis=-1)
        ang = np.arccos(np.clip((v * axis[None]).sum(-1) / np.maximum(dist, 1e-9), -1.0, 1.0))
        margin = np.where(dist > radius, np.arcsin(np.minimum(radius / np.maximum(dist, 1e-9), 1.0)), np.pi)
        nearest = np.maximum(ang - margin, 0.0)
        cone = np.where(nearest < cut[None], np.clip((cut - nearest) / np.maximum(cut - beam, 1e-6), 0.0, 1.0), 0.0)
        for sl in np.unique(arrays["slot"][arrays["slot"] > 0]):
            k = np.flatnonzero(arrays["slot"] == sl)
            local = np.stack([(v[:, k] * arrays[c][k][None]).sum(-1) for c in ("left", "up", "axis")], -1)
            cone[:, k] *= spot_pattern.coarse_bound(arrays["pyramids"][sl], arrays["texture_cut_deg"][sl],
                                                    local, margin[:, k])
        geo = cone / r2
        for c, (a, sign) in enumerate(SIDES):
            # v = cube centre − lamp; the lamp is in front of some point of the cube on side `sign`
            # along axis a when sign · (lamp − cube's far face) > 0, i.e. −sign · v_a + half > 0
            front = -sign * v[..., a] + half > 0
            bound[c] = np.maximum(bound[c], geo * np.where(front, 1.0 + COS_FLOOR, BACK_FLOOR))
    # each lamp's share of the cell's bound in each band
    intensity = band_intensity(arrays)
    k = min(CANDIDATES, len(pos))
    orders, valids = [], []
    for c in range(len(SIDES)):
        light = bound[c][:, :, None] * intensity[None]                                             # cells × lamps × bands
        score = (light / np.maximum(light.sum(1, keepdims=True), 1e-300)).max(-1)
        orders.append(np.argsort(-score, axis=1, kind="stable")[:, :k])
        valids.append(np.take_along_axis(bound[c] * intensity.max(1)[None], orders[-1], 1) > 0)
    order, valid = np.stack(orders, 1), np.stack(valids, 1)                                          # cells × sides × k
    if k < CANDIDATES:                                  # fewer lamps than slots: flagged-off padding
        order = np.pad(order, ((0, 0), (0, 0), (0, CANDIDATES - k)))
        valid = np.pad(valid, ((0, 0), (0, 0), (0, CANDIDATES - k)))
    return {"origin": lo, "cells": n, "candidates": order.astype(np.uint32).ravel(),
            "valid": valid.astype(np.float32).ravel()}


def band_intensity(arrays: dict) -> np.ndarray:
    """Each lamp's mean on-axis intensity (W/sr/nm) in each of SHAPE_BANDS_NM (lamps × bands)."""
    table = arrays["shape_table"].reshape(-1, SHAPE_WL_COUNT)
    wl = SHAPE_WL0_NM + np.arange(SHAPE_WL_COUNT)
    band = np.stack([table[:, (wl >= a) & (wl < b)].mean(1) for a, b in SHAPE_BANDS_NM], 1)       # kinds × bands
    return arrays["scale"][:, None] * band[arrays["kind"]]


def cell_side(grid: dict, points_m: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """The (cell, side) slot of each point (P×3, geometric normals P×3) in the candidate grid, as
    the emitter picks it: cell y-major then x, clamped to the grid; side the normal's dominant axis
    and sign, in SIDES order (z wins ties, then y)."""
    origin, (nx, ny) = grid["origin"], grid["cells"]
    ix = np.clip(np.floor((points_m[:, 0] - origin[0]) / CELL_M), 0, nx - 1).astype(np.int64)
    iy = np.clip(np.floor((points_m[:, 1] - origin[1]) / CELL_M), 0, ny - 1).astype(np.int64)
    a = np.abs(normals)
    axis = np.where((a[:, 2] >= a[:, 0]) & (a[:, 2] >= a[:, 1]), 2, np.where(a[:, 1] >= a[:, 0], 1, 0))
    negative = normals[np.arange(len(normals)), axis] < 0
    return (iy * nx + ix) * len(SIDES) + 2 * axis + negative


def global_table(flux: np.ndarray) -> np.ndarray:
    """The probabilities of the lamps in the global share: UNIFORM_SHARE of them alike, the rest by flux."""
    flux = np.asarray(flux, np.float64)
    return UNIFORM_SHARE / len(flux) + (1.0 - UNIFORM_SHARE) * flux / flux.sum()


def _register() -> None:
    """Register the `lamp_set` emitter plugin for the current Mitsuba variant (once)."""
    import drjit as dr
    import mitsuba as mi

    if mi.variant() in _REGISTERED:
        return

    class LampSet(mi.Emitter):
        """A set of spot lamps sampled by their light at the shading point (module docstring)."""

        def __init__(self, props):
            mi.Emitter.__init__(self, props)
            self.m_flags = mi.EmitterFlags.DeltaPosition
            self.set_key = props["set"]
            s = _SETS[self.set_key]
            self.count = len(s["scale"])
            self.params = {name: mi.Float(np.asarray(col, np.float32)) for name, col in (
                ("px", s["pos"][:, 0]), ("py", s["pos"][:, 1]), ("pz", s["pos"][:, 2]), ("ax", s["axis"][:, 0]),
                ("ay", s["axis"][:, 1]), ("az", s["axis"][:, 2]), ("lx", s["left"][:, 0]), ("ly", s["left"][:, 1]),
                ("lz", s["left"][:, 2]), ("ux", s["up"][:, 0]), ("uy", s["up"][:, 1]), ("uz", s["up"][:, 2]),
                ("cos_cut", s["cos_cut"]), ("cos_beam", s["cos_beam"]), ("cut", s["cut"]), ("inv_tw", s["inv_tw"]),
                ("uv_factor", s["uv_factor"]), ("scale", s["scale"]))}
            self.kind = mi.UInt32(np.asarray(s["kind"], np.uint32))
            self.slot = mi.UInt32(np.asarray(s["slot"], np.uint32))
            self.spectra = [mi.load_dict(d) for d in s["spectra"]]
            self.textures = list(s["textures"])
            self.coarse = mi.Float(np.concatenate([p[0].ravel() for p in s["pyramids"]]).astype(np.float32))
            self.shape_table = mi.Float(np.asarray(s["shape_table"], np.float32))
            g = s["grid"]
            self.origin, self.nx, self.ny = (float(g["origin"][0]), float(g["origin"][1])), *(int(c) for c in g["cells"])
            self.candidates = mi.UInt32(g["candidates"])
            self.valid = mi.Float(g["valid"])
            self.table = mi.DiscreteDistribution(mi.Float(np.asarray(global_table(s["flux"]), np.float32)))

        def _lamp(self, k):
            """The parameters of the lamps k (UInt32 indices)."""
            lamp = {name: dr.gather(mi.Float, col, k) for name, col in self.params.items()}
            lamp["slot"] = dr.gather(mi.UInt32, self.slot, k)
            lamp["kind"] = dr.gather(mi.UInt32, self.kind, k)
            return lamp

        @staticmethod
        def _uv(lamp, to_point):
            """Mitsuba's spot uv of the unit direction to_point (from the lamp), and its cosine to the axis."""
            z = to_point.x * lamp["ax"] + to_point.y * lamp["ay"] + to_point.z * lamp["az"]
            scale = 0.5 / (dr.select(z > 1e-6, z, 1.0) * lamp["uv_factor"])
            x = to_point.x * lamp["lx"] + to_point.y * lamp["ly"] + to_point.z * lamp["lz"]
            y = to_point.x * lamp["ux"] + to_point.y * lamp["uy"] + to_point.z * lamp["uz"]
            return mi.Point2f(0.5 + x * scale, 0.5 + y * scale), z

        def _weight(self, lamp, it, kinds):
            """w_k(x) of the gathered lamps at the shading point it (module docstring); kinds: _kinds(it)."""
            d = mi.Vector3f(lamp["px"], lamp["py"], lamp["pz"]) - it.p
            r2 = dr.maximum(dr.squared_norm(d), 1e-8)
            u = d * dr.rsqrt(r2)
            uv, cos_l = self._uv(lamp, -u)
            cone = dr.clip((cos_l - lamp["cos_cut"]) / (lamp["cos_beam"] - lamp["cos_cut"]), 0.0, 1.0)
            t = spot_pattern.COARSE_TEXELS
            cell = (dr.clip(mi.UInt32(dr.clip(uv.y, 0.0, 1.0) * t), 0, t - 1) * t
                    + dr.clip(mi.UInt32(dr.clip(uv.x, 0.0, 1.0) * t), 0, t - 1))
            pattern = dr.gather(mi.Float, self.coarse, lamp["slot"] * (t * t) + cell)
            side = dr.maximum(dr.dot(it.n, u) + COS_FLOOR, BACK_FLOOR)
            spectral = kinds[0]
            for j in range(1, len(kinds)):
                spectral = dr.select(lamp["kind"] == j, kinds[j], spectral)
            return lamp["scale"] * spectral * cone * pattern * side / r2

        def _kinds(self, it):
            """Each spectral shape summed over the path's wavelengths (one gather per shape and
            wavelength, not per candidate)."""
            idx = [mi.UInt32(dr.clip(mi.Int32(dr.round(it.wavelengths[i] - SHAPE_WL0_NM)), 0, SHAPE_WL_COUNT - 1))
                   for i in range(len(it.wavelengths))]
            return [sum((dr.gather(mi.Float, self.shape_table, j * SHAPE_WL_COUNT + i) for i in idx), mi.Float(0.0))
                    for j in range(len(self.spectra))]

        def _candidates(self, it):
            """(indices, weights at it) of the CANDIDATES lamps of it's grid cell."""
            ix = dr.clip(mi.Int32(dr.floor((it.p.x - self.origin[0]) / CELL_M)), 0, self.nx - 1)
            iy = dr.clip(mi.Int32(dr.floor((it.p.y - self.origin[1]) / CELL_M)), 0, self.ny - 1)
            n = it.n
            ax, ay, az = dr.abs(n.x), dr.abs(n.y), dr.abs(n.z)
            u32 = mi.UInt32
            side = dr.select((az >= ax) & (az >= ay), dr.select(n.z < 0, u32(5), u32(4)),
                             dr.select(ay >= ax, dr.select(n.y < 0, u32(3), u32(2)), dr.select(n.x < 0, u32(1), u32(0))))
            base = (mi.UInt32(iy * self.nx + ix) * len(SIDES) + side) * CANDIDATES
            ids, weights, kinds = [], [], self._kinds(it)
            for j in range(CANDIDATES):
                k = dr.gather(mi.UInt32, self.candidates, base + j)
                ids.append(k)
                weights.append(dr.gather(mi.Float, self.valid, base + j) * self._weight(self._lamp(k), it, kinds))
            return ids, weights

        def sample_direction(self, it, sample, active=True):
            ids, weights = self._candidates(it)
            total = weights[0]
            for w in weights[1:]:
                total = total + w
            local_share = dr.select(total > 0, 1.0 - GLOBAL_SHARE, 0.0)
            local = sample.x < local_share
            u = sample.x / dr.select(local_share > 0, local_share, 1.0) * total
            cum, done, k_local = mi.Float(0.0), mi.Bool(False), ids[-1]
            for k, w in zip(ids, weights):
                take = ~done & (u < cum + w) & (w > 0)
                k_local = dr.select(take, k, k_local)
                done = done | take
                cum = cum + w
            u_global = dr.clip((sample.x - local_share) / (1.0 - local_share), 0.0, 1.0 - 1e-7)
            k = dr.select(local, k_local, self.table.sample(u_global, active))
            w_k = mi.Float(0.0)
            for kj, w in zip(ids, weights):
                w_k += dr.select(kj == k, w, 0.0)
            pdf = (local_share * w_k / dr.select(total > 0, total, 1.0)
                   + (1.0 - local_share) * self.table.eval_pmf_normalized(k, active))
            lamp = self._lamp(k)
            ok = active & (pdf > 0)
            p = mi.Point3f(lamp["px"], lamp["py"], lamp["pz"])
            d = p - it.p
            dist = dr.norm(d)
            ds = dr.zeros(mi.DirectionSample3f)
            ds.p, ds.d, ds.dist, ds.n = p, d / dist, dist, mi.Normal3f(0.0)
            ds.pdf, ds.delta, ds.time = dr.select(ok, pdf, 0.0), True, it.time
            ds.emitter = mi.EmitterPtr(self)
            cos_t = -(ds.d.x * lamp["ax"] + ds.d.y * lamp["ay"] + ds.d.z * lamp["az"])
            falloff = dr.select(cos_t >= lamp["cos_beam"], 1.0,
                                (lamp["cut"] - dr.acos(dr.clip(cos_t, -1.0, 1.0))) * lamp["inv_tw"])
            falloff = dr.select(cos_t > lamp["cos_cut"], falloff, 0.0)
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = it.wavelengths
            kind = lamp["kind"]
            spec = self.spectra[0].eval(si, ok)
            for j, tex in enumerate(self.spectra[1:], start=1):
                spec = dr.select(kind == j, tex.eval(si, ok), spec)
            if self.textures:
                si.uv, _ = self._uv(lamp, -ds.d)
                for j, tex in enumerate(self.textures, start=1):
                    falloff = dr.select(lamp["slot"] == j, falloff * tex.eval_1(si, ok & (lamp["slot"] == j)), falloff)
            value = spec * (lamp["scale"] * falloff / (dist * dist) / dr.select(ok, pdf, 1.0))
            return ds, dr.select(ok, value, 0.0)

        def pdf_direction(self, it, ds, active=True):
            return mi.Float(0.0)

        def eval_direction(self, it, ds, active=True):
            return dr.zeros(mi.Spectrum)

        def eval(self, si, active=True):
            return dr.zeros(mi.Spectrum)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"LampSet[{self.count} lamps, {self.nx}×{self.ny} cells]"

    mi.register_emitter(PLUGIN, lambda props: LampSet(props))
    _REGISTERED.add(mi.variant())


def lamp_set_emitter(spots: dict) -> dict:
    """One Mitsuba emitter dict (a spectral variant must be set) holding the `spot_emitter` dicts
    `spots` (≥ 1), sampled per shading point (module docstring); its sampling_weight, its share
    of Mitsuba's light selection against other emitters, is the sum of theirs."""
    if not spots:
        raise InvalidValueError("lamp set: no lamps given")
    arrays = _spot_arrays(spots)
    listed = ("spectra", "grid", "textures", "pyramids", "texture_cut_deg")
    key = hashlib.sha1(b"".join(np.ascontiguousarray(v).tobytes() for k, v in arrays.items() if k not in listed)
                       + repr(arrays["spectra"]).encode() + repr([id(t) for t in arrays["textures"]]).encode()).hexdigest()
    _SETS.pop(key, None)
    _SETS[key] = arrays
    while len(_SETS) > MAX_SETS:                    # the oldest first: a long data set stays small
        _SETS.pop(next(iter(_SETS)))
    _register()
    return {"type": PLUGIN, "set": key, "sampling_weight": float(sum(e["sampling_weight"] for e in spots.values()))}
