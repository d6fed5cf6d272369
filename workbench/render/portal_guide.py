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

p_portal picking portal i with probability P_i ∝ Ω̃_i (max(n·ω_i, 0) + COS_FLOOR), Ω̃_i = A cos θ_i / r²
(≤ 2π) the portal's approximate solid angle from x, then a point uniformly on its rectangle
(density r² / (A |cos θ_i|) in solid angle). Every sample is weighted f cos / p(ω) and reported
with p(ω), and `pdf`/`eval_pdf` return the same mixture, so the path integrator's multiple
importance weights stay right: the estimator is unbiased (the expected image is unchanged), and
the bounded weight f cos / p ≤ albedo / (1 − α) keeps it defensive where the portal guess is poor.
This is the BSDF/guide mixture of practical path guiding (Müller, Gross & Novák 2017, α = ½)
with the portals, known from the scene, as the guiding distribution. Delta lobes (a wet film, a
window's mirror) pass through with their discrete probability × (1 − α). Outside the box α = 0:
the wrapper is the nested BSDF.
"""
from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from workbench.errors import InvalidValueError

GUIDE_SHARE = 0.5          # α: share of samples sent toward the portals inside the tunnel
COS_FLOOR = 0.05           # keeps a portal at the receiver's horizon possible
BOX_MARGIN_M = 0.05        # the box grown across (not along) the tunnel: surfaces on its faces are inside
_CLASSES: dict[str, type] = {}
_ENABLED = [True]          # off only inside unguided(): the benchmark's 'before'


@contextmanager
def unguided():
    """Scenes built inside the block are not guided (guide_toward_portals returns BSDFs as they
    are): the render-noise benchmark's 'before', with the same expected image."""
    _ENABLED.append(False)
    try:
        yield
    finally:
        _ENABLED.pop()


def _bsdf_class():
    """The PortalGuide BSDF class for the current Mitsuba variant (made once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _CLASSES:
        return _CLASSES[variant]

    class PortalGuide(mi.BSDF):
        """A BSDF whose samples inside a tunnel go partly toward its portals (module docstring)."""

        def __init__(self, props, nested, box_m):
            mi.BSDF.__init__(self, props)
            self.nested = nested
            (self.x0, self.y0, self.z0), (self.x1, self.y1, self.z1) = box_m
            self.area = (self.x1 - self.x0) * (self.z1 - self.z0)
            self.m_flags = nested.flags()
            self.m_components = [nested.flags(i) for i in range(nested.component_count())]

        def _alpha(self, si):
            p, e = si.p, BOX_MARGIN_M      # the walls, road and soffit lie on the box's faces
            inside = ((p.x > self.x0 - e) & (p.x < self.x1 + e) & (p.y > self.y0) & (p.y < self.y1) &
                      (p.z > self.z0 - e) & (p.z < self.z1 + e))
            return dr.select(inside, GUIDE_SHARE, 0.0)

        def _portal_weights(self, si):
            """(P_south, P_north): the portals' selection probabilities at si (sum 1 or 0)."""
            p, n = si.p, si.sh_frame.n
            cx, cz = 0.5 * (self.x0 + self.x1), 0.5 * (self.z0 + self.z1)
            out = []
            for y in (self.y0, self.y1):
                d = mi.Vector3f(cx, y, cz) - p
                r2 = dr.maximum(dr.squared_norm(d), 1e-6)
                u = d * dr.rsqrt(r2)
                omega = dr.minimum(self.area * dr.abs(u.y) / r2, 2 * dr.pi)
                out.append(omega * (dr.maximum(dr.dot(n, u), 0.0) + COS_FLOOR))
            total = out[0] + out[1]
            ok = total > 0
            return dr.select(ok, out[0] / total, 0.0), dr.select(ok, out[1] / total, 0.0)

        def _portal_pdf(self, si, wo_world):
            """Solid-angle density of p_portal for the world direction wo_world."""
            p = si.p
            w_s, w_n = self._portal_weights(si)
            pdf = mi.Float(0.0)
            for y, w in ((self.y0, w_s), (self.y1, w_n)):
                t = (y - p.y) / wo_world.y
                x = p.x + t * wo_world.x
                z = p.z + t * wo_world.z
                hit = (t > 0) & (x >= self.x0) & (x <= self.x1) & (z >= self.z0) & (z <= self.z1)
                pdf += dr.select(hit, w * t * t / (self.area * dr.abs(wo_world.y)), 0.0)
            return pdf

        def _mix_pdf(self, ctx, si, wo, alpha, active):
            """(nested value, mixture pdf) of the local direction wo."""
            value, pdf_b = self.nested.eval_pdf(ctx, si, wo, active)
            pdf_p = self._portal_pdf(si, si.to_world(wo))
            return value, (1 - alpha) * pdf_b + alpha * pdf_p

        def sample(self, ctx, si, sample1, sample2, active=True):
            alpha = self._alpha(si)
            guided = active & (sample1 < alpha)
            s1 = dr.select(guided, 0.0, (sample1 - alpha) / (1 - alpha))
            bs, weight = self.nested.sample(ctx, si, dr.clip(s1, 0.0, 1.0 - 1e-7), sample2, active & ~guided)
            delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            # a portal direction: portal i by sample1 / α against P_i, a point on it by sample2
            w_s, _ = self._portal_weights(si)
            y = dr.select(sample1 < alpha * w_s, self.y0, self.y1)
            q = mi.Point3f(self.x0 + sample2.x * (self.x1 - self.x0), y, self.z0 + sample2.y * (self.z1 - self.z0))
            d = dr.normalize(q - si.p)
            wo = dr.select(guided, si.to_local(d), bs.wo)
            value, pdf = self._mix_pdf(ctx, si, wo, alpha, active & (guided | ~delta))
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


def tunnel_boxes_m(city) -> list[tuple[tuple[float, float, float], tuple[float, float, float]]]:
    """The interior boxes ((x0, y0, z0), (x1, y1, z1), m) of the city's tunnels
    (scene/city/tunnel.py TunnelFrame: between the walls' inner faces, from road to soffit)."""
    out = []
    for obj in (o for o in city.objects if o.class_name == "tunnel"):
        f = obj.meta["frame"]
        out.append(((f.x_m - f.half_width_m, f.y_south_m, f.road_z_m),
                    (f.x_m + f.half_width_m, f.y_north_m, f.soffit_z_m)))
    return out


def guide_toward_portals(bsdf, boxes_m) -> object:
    """`bsdf` guided toward the portals of every tunnel box in boxes_m (one wrapper per box; the
    boxes do not overlap, so at most one guides a point); a BSDF with no smooth lobe (a pane, a
    mirror) is returned as it is: it has no direction to choose."""
    import mitsuba as mi

    if not _ENABLED[-1] or not mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth):
        return bsdf
    for box in boxes_m:
        bsdf = portal_guided(bsdf, box)
    return bsdf


def portal_guided(nested, box_m) -> object:
    """`nested` (a loaded Mitsuba BSDF) wrapped so that inside box_m ((x0, y0, z0), (x1, y1, z1),
    m: the tunnel's interior between its walls, road and soffit; the portals are its faces at y0
    and y1) part of its samples head for the portals."""
    import mitsuba as mi

    lo, hi = (np.asarray(b, dtype=np.float64) for b in box_m)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(np.r_[lo, hi])) or np.any(hi <= lo):
        raise InvalidValueError(f"portal box must be two finite 3-vectors with min < max, got {box_m}")
    return _bsdf_class()(mi.Properties(), nested, (tuple(lo.tolist()), tuple(hi.tolist())))
