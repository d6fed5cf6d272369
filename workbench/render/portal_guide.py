"""Daylight through a tunnel's portals, found by the paths that need it: a BSDF wrapper that sends
part of its samples toward the portals.

Inside a tunnel by day most of the light on the walls, ceiling and road comes in through the two
open ends: sky, and the sunlit road and facades beyond them. Next-event estimation cannot aim at
it (the sky's samples hit the roof; the sunlit ground outside is not a light), so only
BSDF-sampled rays that happen to leave through a portal carry it. From 50 m inside, a 10 × 6 m
portal covers ~0.02 sr, which a cosine-weighted bounce finds about once in 200 samples: the
interior is covered in speckle (issue 33: a tunnel frame cost 26–75× a day frame at the noise
criterion).

`PortalGuide` wraps a surface's BSDF. At a shading point x inside the tunnel's box it draws the
next direction from the one-sample mixture

    p(ω) = (1 − α) p_bsdf(ω) + α p_portal(ω),   α = GUIDE_SHARE,

p_portal picking portal i with probability P_i ∝ S_i (max(n·ω_i, 0) + COS_FLOOR), S_i the
portal's solid angle from x and ω_i the direction to its centre, then a direction uniform in that
solid angle (the spherical-rectangle sampling of Ureña, Fajardo & King 2013). Every sample is
weighted f cos / p(ω) and reported with p(ω), and `pdf`/`eval_pdf` return the same mixture, so the
path integrator's multiple importance weights stay right: the estimator is unbiased (the expected
image is unchanged), and the bounded weight f cos / p ≤ albedo / (1 − α) keeps it defensive where
the portal guess is poor. This is the BSDF/guide mixture of practical path guiding (Müller, Gross
& Novák 2017, α = ½) with the portals, known from the scene, as the guiding distribution. Delta
lobes (a wet film, a window's mirror) pass through with their discrete probability × (1 − α).
Outside the box α = 0: the wrapper is the nested BSDF.

Where the sun shines in through a portal, the floor and walls of its mouth are a second source as
bright as the outside (measured on city_tunnel frame 2: the render-noise p90 3.2 with the portal
as target, 2.0 with the inset). The target is then the tunnel's cross-section as deep inside as
the sunlight reaches (`tunnel_portals`): a direction through it ends on the sunlit mouth or goes
on out of the portal. Points within the mouth aim at the portal itself.

The sky lights every portal's mouth too, sun or not: the floor and walls of its first few tunnel
heights see the sky through the portal (a floor point's view of it falls roughly as (h/d)³ at
depth d, h the tunnel's height), and from deep inside that bright strip lies in front of the
portal target, so only cosine samples found it. Measured on city_tunnel frame 0 (256 one-sample
renders, Mitsuba's path integrator): the heaviest samples on the ceiling 30–40 m in were ceiling →
road or wall within 6 m of the exit → sky, at up to 380× the mean, and white dots where one
sample held over 20 % of a pixel's light. A share β = MOUTH_SHARE of the guided samples therefore
aims at the cross-sections MOUTH_DEPTH_HEIGHTS tunnel heights in (or the sunlit depth, if that is
deeper), the rest at the targets above; both are in `pdf`, so the estimate stays unbiased. On
city_tunnel frames 0–2 (128 one-sample renders each, pixels of the ceiling rows below their 90th
percentile of light) the pixels with one sample over 20 % fell from 207 / 183 / 287 to 29 / 53 / 63
and the 99th percentile of the per-sample relative variance from 12–14 to 4–6, the median held
(1.42 → 1.46, 1.36 → 1.43, 1.97 → 2.00); deeper targets or larger shares took more from the
portal's own light than they gave (3 heights: β 0.25 / 0.35 raised the median to 1.53 / 1.64;
2 heights at β 0.5: 1.68).

Russian roulette is off in a tunnel by day (`roulette_depth`). Mitsuba's path tracer ends a path
at depth ≥ rr_depth (5) with probability 1 − q, q = min(max throughput · η², 0.95), and multiplies a
survivor by 1/q: unbiased, and cheap where the light a path will still find is like the light it
found so far. In a tunnel it is not: a path four bounces deep inside, at throughput ~0.05, lives on
with q ~0.05, weighted ×20, and its next (portal-guided) bounce reaches the sunlit street, 10²–10³×
brighter than the interior. Measured on city_tunnel frame 0 (376×240, 128 one-sample renders,
the same seeds, against a 2,048-spp reference): samples over 100× their pixel's mean fell from 40
to 8 with rr_depth = max_depth, pixels more than twice the reference (the white dots on the
ceiling, walls and walkway) from 76 to 2, the relative RMS error from 0.158 to 0.102, the mean
unchanged (0.025858 → 0.025857), for ~15 % more CPU time. The same render without the paths of
five bounces (max_depth 5) also loses its dots, but is 1.8 % darker: the light is real, only its
sampling was poor.
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render.switch import Switch

GUIDE_SHARE = 0.5          # α: share of samples sent toward the portals inside the tunnel
MOUTH_DEPTH_HEIGHTS = 3.0  # the sky-lit mouth's depth, in tunnel heights (module docstring)
MOUTH_SHARE = 0.15         # β: share of the guided samples aimed past the sky-lit mouth
COS_FLOOR = 0.05           # keeps a portal at the receiver's horizon possible
MITSUBA_RR_DEPTH = 5       # Mitsuba's path integrator's default rr_depth
BOX_MARGIN_M = 0.05        # the box grown across (not along) the tunnel: surfaces on its faces are inside
_CLASSES: dict[str, type] = {}
_SWITCH = Switch()         # off only inside unguided(): the benchmark's 'before'


def roulette_depth(portals: list, max_depth: int) -> int:
    """The path integrator's rr_depth: max_depth (no Russian roulette) in a city with tunnels by
    day (`portals`: tunnel_portals, empty at night or without tunnels), else Mitsuba's default 5
    (module docstring)."""
    return int(max_depth) if portals else MITSUBA_RR_DEPTH


def inside_tunnel(p, box_m):
    """Dr.Jit mask of the points p inside a tunnel's box ((x0, y0, z0), (x1, y1, z1), m), grown by
    BOX_MARGIN_M across it so that its walls, road and soffit count as inside, not along it."""
    (x0, y0, z0), (x1, y1, z1), e = *box_m, BOX_MARGIN_M
    return (p.x > x0 - e) & (p.x < x1 + e) & (p.y > y0) & (p.y < y1) & (p.z > z0 - e) & (p.z < z1 + e)


def unguided():
    """Scenes built inside the block are not guided (guide_toward_portals returns BSDFs as they
    are): the render-noise benchmark's 'before', with the same expected image."""
    return _SWITCH.off()


def _bsdf_class():
    """The PortalGuide BSDF class for the current Mitsuba variant (made once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _CLASSES:
        return _CLASSES[variant]

    class PortalGuide(mi.BSDF):
        """A BSDF whose samples inside a tunnel go partly toward its portals (module docstring)."""

        def __init__(self, props, nested, box_m, insets_m, mouth_m):
            mi.BSDF.__init__(self, props)
            self.nested = nested
            (self.x0, self.y0, self.z0), (self.x1, self.y1, self.z1) = box_m
            # (south inset m, north inset m, share) of each target: the sunlit depth (or the portal)
            # and, where it lies deeper at either portal, the sky-lit mouth's depth with share β
            (d0, d1), m = insets_m, mouth_m
            deeper = m > min(d0, d1)
            self.plans = [(d0, d1, 1.0 - MOUTH_SHARE if deeper else 1.0)]
            if deeper:
                self.plans.append((max(d0, m), max(d1, m), MOUTH_SHARE))
            self.m_flags = nested.flags()
            self.m_components = [nested.flags(i) for i in range(nested.component_count())]

        def _alpha(self, si):
            box = ((self.x0, self.y0, self.z0), (self.x1, self.y1, self.z1))
            return dr.select(inside_tunnel(si.p, box), GUIDE_SHARE, 0.0)

        def _planes(self, p):
            """[(y, share)] of the target rectangles seen from p: per plan and portal, its
            cross-section inset by the plan's depth, or the portal itself from within that depth."""
            out = []
            for d0, d1, share in self.plans:
                ys, yn = self.y0 + d0, self.y1 - d1
                out += [(dr.select(p.y > ys, ys, self.y0), share), (dr.select(p.y < yn, yn, self.y1), share)]
            return out

        def _rect(self, p, y):
            """The portal at y seen from p as a spherical rectangle (Ureña, Fajardo & King 2013,
            'An area-preserving parametrization for spherical rectangles'): its local frame
            (x across, y up, z toward p's side of the plane, z0 < 0), the bounds, b0, b1, k and
            the solid angle S (sr)."""
            x0, x1 = self.x0 - p.x, self.x1 - p.x
            y0, y1 = self.z0 - p.z, self.z1 - p.z
            z0 = -dr.maximum(dr.abs(y - p.y), 1e-6)
            l0, l1 = dr.sqrt(z0 * z0 + y0 * y0), dr.sqrt(z0 * z0 + x1 * x1)
            l2, l3 = dr.sqrt(z0 * z0 + y1 * y1), dr.sqrt(z0 * z0 + x0 * x0)
            g0 = dr.acos(dr.clip(y0 * x1 / (l0 * l1), -1.0, 1.0))
            g1 = dr.acos(dr.clip(-x1 * y1 / (l1 * l2), -1.0, 1.0))
            g2 = dr.acos(dr.clip(x0 * y1 / (l2 * l3), -1.0, 1.0))
            g3 = dr.acos(dr.clip(-x0 * y0 / (l3 * l0), -1.0, 1.0))
            k = 2 * dr.pi - g2 - g3
            return {"x0": x0, "x1": x1, "y0": y0, "y1": y1, "z0": z0, "b0": -y0 / l0, "b1": y1 / l2, "k": k,
                    "S": dr.maximum(g0 + g1 - k, 0.0)}

        @staticmethod
        def _rect_point(r, u, v):
            """(x, z) offsets from p of the point on the portal whose direction is uniform in
            solid angle for the unit sample (u, v) (the same paper's sampling)."""
            au = u * r["S"] + r["k"]
            fu = (dr.cos(au) * r["b0"] - r["b1"]) / dr.sin(au)
            cu = dr.clip(dr.select(fu >= 0, 1.0, -1.0) * dr.rsqrt(fu * fu + r["b0"] * r["b0"]), -1.0, 1.0)
            xu = dr.clip(-(cu * r["z0"]) * dr.rsqrt(dr.maximum(1 - cu * cu, 1e-12)), r["x0"], r["x1"])
            d = dr.sqrt(xu * xu + r["z0"] * r["z0"])
            h0 = r["y0"] * dr.rsqrt(d * d + r["y0"] * r["y0"])
            h1 = r["y1"] * dr.rsqrt(d * d + r["y1"] * r["y1"])
            hv = h0 + v * (h1 - h0)
            yv = dr.select(hv * hv < 1 - 1e-6, hv * d * dr.rsqrt(dr.maximum(1 - hv * hv, 1e-12)), r["y1"])
            return xu, dr.clip(yv, r["y0"], r["y1"])

        def _target_weights(self, si, planes, rects):
            """The targets' selection probabilities at si (sum 1, or all 0): per plan in its share,
            the portals ∝ S_i (max(n·ω_i, 0) + COS_FLOOR)."""
            p, n = si.p, si.sh_frame.n
            cx, cz = 0.5 * (self.x0 + self.x1), 0.5 * (self.z0 + self.z1)
            out = []
            for k in range(0, len(planes), 2):
                pair = []
                for (y, _), r in zip(planes[k:k + 2], rects[k:k + 2]):
                    u = dr.normalize(mi.Vector3f(cx, y, cz) - p)
                    pair.append(r["S"] * (dr.maximum(dr.dot(n, u), 0.0) + COS_FLOOR))
                total = pair[0] + pair[1]
                ok = total > 0
                out += [dr.select(ok, planes[k][1] * w / total, 0.0) for w in pair]
            return out

        def _targets(self, si):
            """(plane y's, spherical rectangles, selection probabilities) of the targets at si."""
            planes = self._planes(si.p)
            rects = [self._rect(si.p, y) for y, _ in planes]
            return [y for y, _ in planes], rects, self._target_weights(si, planes, rects)

        def _portal_pdf(self, si, wo_world, targets):
            """Solid-angle density of p_portal for the world direction wo_world."""
            p = si.p
            pdf = mi.Float(0.0)
            for y, r, w in zip(*targets):
                t = (y - p.y) / wo_world.y
                x = p.x + t * wo_world.x
                z = p.z + t * wo_world.z
                hit = (t > 0) & (x >= self.x0) & (x <= self.x1) & (z >= self.z0) & (z <= self.z1) & (r["S"] > 0)
                pdf += dr.select(hit, w / r["S"], 0.0)
            return pdf

        def _mix_pdf(self, ctx, si, wo, alpha, active, targets=None):
            """(nested value, mixture pdf) of the local direction wo."""
            value, pdf_b = self.nested.eval_pdf(ctx, si, wo, active)
            pdf_p = self._portal_pdf(si, si.to_world(wo), targets or self._targets(si))
            return value, (1 - alpha) * pdf_b + alpha * pdf_p

        def sample(self, ctx, si, sample1, sample2, active=True):
            alpha = self._alpha(si)
            guided = active & (sample1 < alpha)
            s1 = dr.select(guided, 0.0, (sample1 - alpha) / (1 - alpha))
            bs, weight = self.nested.sample(ctx, si, dr.clip(s1, 0.0, 1.0 - 1e-7), sample2, active & ~guided)
            delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            # a portal direction: target i by sample1 / α against P_i, uniform in its solid angle by sample2
            targets = self._targets(si)
            planes, rects, weights = targets
            cum, bounds = mi.Float(0.0), []
            for w in weights[:-1]:
                cum = cum + alpha * w
                bounds.append(cum)
            r, y = rects[-1], planes[-1]
            for i in reversed(range(len(bounds))):   # the first target whose cumulative P passes sample1
                pick = sample1 < bounds[i]
                r = {key: dr.select(pick, rects[i][key], r[key]) for key in r}
                y = dr.select(pick, planes[i], y)
            dx, dz = self._rect_point(r, sample2.x, sample2.y)
            d = dr.normalize(mi.Vector3f(dx, y - si.p.y, dz))
            wo = dr.select(guided, si.to_local(d), bs.wo)
            value, pdf = self._mix_pdf(ctx, si, wo, alpha, active & (guided | ~delta), targets)
            ok = active & (pdf > 0) & (guided | ~delta)
            out = dr.zeros(mi.BSDFSample3f)
            out.wo = wo
            out.eta = dr.select(guided, 1.0, bs.eta)
            out.pdf = dr.select(delta & ~guided, (1 - alpha) * bs.pdf, dr.select(ok, pdf, 0.0))
            reflect = mi.UInt32(int(mi.BSDFFlags.DiffuseReflection))
            out.sampled_type = dr.select(guided, reflect, bs.sampled_type)
            out.sampled_component = dr.select(guided, mi.UInt32(0), bs.sampled_component)
            smooth_weight = dr.select(ok, value / dr.select(ok, pdf, 1.0), 0.0)
            return out, dr.select(delta & ~guided, weight / (1 - alpha), smooth_weight)

        def eval(self, ctx, si, wo, active=True):
            return self.nested.eval(ctx, si, wo, active)

        def pdf(self, ctx, si, wo, active=True):
            return self._mix_pdf(ctx, si, wo, self._alpha(si), active)[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            return self._mix_pdf(ctx, si, wo, self._alpha(si), active)

        def eval_diffuse_reflectance(self, si, active=True):
            return self.nested.eval_diffuse_reflectance(si, active)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"PortalGuide[{self.nested}]"

    _CLASSES[variant] = PortalGuide
    return PortalGuide


def tunnel_portals(city, daylight) -> list[tuple[tuple, tuple[float, float]]]:
    """(box, insets) of the city's tunnels: the interior box ((x0, y0, z0), (x1, y1, z1), m;
    scene/city/tunnel.py TunnelFrame: between the walls' inner faces, from road to soffit; the
    portals are its faces at y0 and y1) and how far the sun shines in through each portal along
    the tunnel (m: soffit height × |s_y| / s_z for the sun's direction s, 0 at the portal the sun
    does not face or without a sun), within which the floor is a second source of light."""
    from workbench.render.daylight import sun_angles, sun_direction

    sun = daylight.sun_scale > 0 and daylight.sky_model != "overcast"
    s = sun_direction(*sun_angles(daylight)) if sun else np.array([0.0, 0.0, 1.0])
    out = []
    for obj in (o for o in city.objects if o.class_name == "tunnel"):
        f = obj.meta["frame"]
        depth = min((f.soffit_z_m - f.road_z_m) * abs(s[1]) / s[2], (f.y_north_m - f.y_south_m) / 3)
        insets = (depth if s[1] < 0 else 0.0, depth if s[1] > 0 else 0.0)   # sunlight travels along −s
        out.append((((f.x_m - f.half_width_m, f.y_south_m, f.road_z_m),
                     (f.x_m + f.half_width_m, f.y_north_m, f.soffit_z_m)), insets))
    return out


def guide_toward_portals(bsdf, portals) -> object:
    """`bsdf` guided toward the portals of every (box, insets) in `portals` (one wrapper per
    tunnel; tunnels do not overlap, so at most one guides a point); a BSDF with no smooth lobe (a
    pane, a mirror) is returned as it is: it has no direction to choose."""
    import mitsuba as mi

    if not _SWITCH.on or not mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth):
        return bsdf
    for box, insets in portals:
        bsdf = portal_guided(bsdf, box, insets)
    return bsdf


def portal_guided(nested, box_m, insets_m=(0.0, 0.0), mouth_m: float | None = None) -> object:
    """`nested` (a loaded Mitsuba BSDF) wrapped so that inside box_m ((x0, y0, z0), (x1, y1, z1),
    m: the tunnel's interior between its walls, road and soffit; the portals are its faces at y0
    and y1) part of its samples head for the portals, or for the cross-sections insets_m (south,
    north; m) inside them, and a share β for the cross-sections mouth_m deep (m; default
    MOUTH_DEPTH_HEIGHTS tunnel heights, at most a third of its length; 0: none)."""
    import mitsuba as mi

    lo, hi = (np.asarray(b, dtype=np.float64) for b in box_m)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(np.r_[lo, hi])) or np.any(hi <= lo):
        raise InvalidValueError(f"portal box must be two finite 3-vectors with min < max, got {box_m}")
    d0, d1 = (float(d) for d in insets_m)
    if not (0 <= d0 and 0 <= d1 and d0 + d1 < hi[1] - lo[1]):
        raise InvalidValueError(f"portal insets {insets_m} m must be ≥ 0 and together shorter than the tunnel "
                                f"({hi[1] - lo[1]:g} m)")
    mouth = min(MOUTH_DEPTH_HEIGHTS * (hi[2] - lo[2]), (hi[1] - lo[1]) / 3) if mouth_m is None else float(mouth_m)
    if not 0 <= mouth < (hi[1] - lo[1]) / 2:
        raise InvalidValueError(f"the sky-lit mouth's depth {mouth:g} m must be ≥ 0 and under half the tunnel's "
                                f"length ({hi[1] - lo[1]:g} m)")
    return _bsdf_class()(mi.Properties(), nested, (tuple(lo.tolist()), tuple(hi.tolist())), (d0, d1), mouth)
