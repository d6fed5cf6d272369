"""By day in a tunnel city: the sun and a tunnel's luminaire row as one emitter that picks between
them per shading point, by where each can light it.

Mitsuba picks the light for next-event estimation from one distribution for the whole scene (the
emitters' `sampling_weight`). In a tunnel by day three lights shared it equally: the sun, the sky
and the luminaire row. Inside the tunnel the sun cannot reach a point beyond its sunlit mouth;
outside, the row lights nothing; yet each light was picked a third of the time everywhere, and a
light picked with probability p adds a selection variance (1 − p)/p = 2 to its own. Measured on
city_tunnel frame 0 (render noise at a fixed exposure, 32 spp against 256): the sunlight that
reaches the interior after one bounce outside (portal-guided bounces, portal_guide.py, land on
the sunlit road beyond a portal, whose sun estimate was picked a third of the time) carried ~84 %
of the render-noise power; a global re-weighting (sun 8, row 4, sky 1) took the median ratio
from 1.02 to 0.87 and no further, because what each point needs differs.

Here the row's emitter also carries the sun, and the scene has no separate sun. At a shading
point p it picks the sun with probability q(p), the row with 1 − q(p):

    q = SUN_SHARE_UNLIT  inside the tunnel's box beyond the sun's reach (the sunlit depth of a
                         portal the sun shines into: portal_guide.tunnel_portals),
    q = SUN_SHARE_LIT    elsewhere: outside the box and within the sunlit mouth (a middle share
                         there measured worse on city_tunnel frame 2: median ratio at 64 spp
                         0.80 with ½, 0.74 with 0.8, 0.73 with 0.95).

The sun branch is Mitsuba's `directional` emitter (a delta direction: irradiance E(λ), pdf 1),
its weight E/q; the row branch is the row's own sampler (luminaire_row.py) with its density × (1 − q)
and weight ÷ (1 − q), and pdf_direction reports (1 − q(p)) × the row's density, so the multiple
importance weight of a BSDF-sampled ray that hits a lens stays right. Every q lies strictly
between 0 and 1, so each light keeps a positive probability wherever it could shine and the
estimator is unbiased (the expected image is unchanged); a poor guess of where a light reaches
costs variance only. The emitter weighs ROW_AND_SUN_WEIGHT (shared by a city's tunnels) against
the sky's 1 in the scene's light selection.
"""
from __future__ import annotations

import numpy as np

from workbench.render.switch import Switch

SUN_SHARE_UNLIT = 0.05       # the sun's share of a point in the tunnel beyond its reach
SUN_SHARE_LIT = 0.95         # and elsewhere: there the row's light is small beside the daylight
ROW_AND_SUN_WEIGHT = 16.0    # the row-and-sun emitters' weight in light selection against the sky's 1: the
                             # sky is found by BSDF samples too (measured on city_tunnel frame 0 at 32 spp,
                             # median ratio: weight 2 0.69, 4 0.62, 8 0.58, 16 0.56)
PLUGIN = "luminaire_row_sun"
_REGISTERED: set[str] = set()
_SWITCH = Switch()           # off only inside separate_sun(): the benchmark's 'before'


def separate_sun():
    """Scenes built inside the block keep the sun as its own emitter (row_sun_shares returns
    nothing): the render-noise benchmark's 'before', with the same expected image."""
    return _SWITCH.off()


def row_and_sun_plugin() -> str:
    """Register the row-and-sun emitter for the current Mitsuba variant (once); its plugin name."""
    import drjit as dr
    import mitsuba as mi

    from workbench.render.luminaire_row import row_emitter_class
    from workbench.render.portal_guide import BOX_MARGIN_M

    if mi.variant() in _REGISTERED:
        return PLUGIN
    row = row_emitter_class()

    class RowAndSun(row):
        """A luminaire row that also carries the sun, chosen per shading point (module docstring)."""

        def __init__(self, props):
            row.__init__(self, props)
            self.sun_irradiance = props["sun_irradiance"]
            self.sun = tuple(float(props[k]) for k in ("sun_x", "sun_y", "sun_z"))    # toward the sun
            self.sun_distance = float(props["sun_distance_m"])
            self.box = tuple(float(props[k]) for k in ("box_x0", "box_y0", "box_z0", "box_x1", "box_y1", "box_z1"))
            self.mouth = (float(props["sunlit_depth_south_m"]), float(props["sunlit_depth_north_m"]))

        def sun_share(self, p):
            """q(p): the probability of picking the sun at the shading point p."""
            (x0, y0, z0, x1, y1, z1), e = self.box, BOX_MARGIN_M
            inside = (p.x > x0 - e) & (p.x < x1 + e) & (p.y > y0) & (p.y < y1) & (p.z > z0 - e) & (p.z < z1 + e)
            mouth = (p.y < y0 + self.mouth[0]) | (p.y > y1 - self.mouth[1])
            return dr.select(inside & ~mouth, SUN_SHARE_UNLIT, SUN_SHARE_LIT)

        def sample_direction(self, it, sample, active=True):
            q = self.sun_share(it.p)
            sun = active & (sample.x < q)
            x_row = dr.clip((sample.x - q) / (1.0 - q), 0.0, 1.0 - 1e-7)
            ds, value = row.sample_direction(self, it, mi.Point2f(x_row, sample.y), active & ~sun)
            d = mi.Vector3f(*self.sun)
            out = dr.zeros(mi.DirectionSample3f)
            out.p = dr.select(sun, it.p + d * self.sun_distance, ds.p)
            out.n = dr.select(sun, -d, ds.n)
            out.d = dr.select(sun, d, ds.d)
            out.dist = dr.select(sun, self.sun_distance, ds.dist)
            out.pdf = dr.select(sun, q, ds.pdf * (1.0 - q))
            out.delta = sun
            out.time = it.time
            out.emitter = mi.EmitterPtr(self)
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = it.wavelengths
            e_sun = self.sun_irradiance.eval(si, sun)
            return out, dr.select(sun, e_sun / q, value / (1.0 - q))

        def pdf_direction(self, it, ds, active=True):
            return (1.0 - self.sun_share(it.p)) * row.pdf_direction(self, it, ds, active)

        def to_string(self):
            return f"RowAndSun[{self.n} lenses every {self.spacing} m, the sun]"

    mi.register_emitter(PLUGIN, lambda props: RowAndSun(props))
    _REGISTERED.add(mi.variant())
    return PLUGIN


def row_sun_shares(city, portals: list, sun_emitter: dict | None) -> dict[int, dict]:
    """{tunnel instance id: {'sampling_weight', 'plugin' (registered), 'sun': the sun's properties}}
    for every tunnel of the city when the scene has a sun (sun_emitter: sky.daylight_emitters'
    'sun' dict; portals: portal_guide.tunnel_portals of the city, one (box, sunlit depths) per
    tunnel in the city's order); {} without a sun, without tunnels, or inside separate_sun()."""
    import mitsuba as mi

    tunnels = [o for o in city.objects if o.class_name == "tunnel"]
    if sun_emitter is None or not tunnels or not _SWITCH.on:
        return {}
    toward_sun = -np.asarray(sun_emitter["direction"], dtype=np.float64)
    toward_sun /= np.linalg.norm(toward_sun)
    x0, y0, x1, y1 = city.extent_m
    distance = 2.0 * (float(np.hypot(x1 - x0, y1 - y0)) + 1000.0)      # beyond everything, as Mitsuba's 2R
    irradiance = mi.load_dict(sun_emitter["irradiance"])
    out = {}
    for obj, (box, (south, north)) in zip(tunnels, portals, strict=True):
        (bx0, by0, bz0), (bx1, by1, bz1) = box
        sun = {"sun_irradiance": irradiance, "sun_distance_m": distance,
               "sun_x": float(toward_sun[0]), "sun_y": float(toward_sun[1]), "sun_z": float(toward_sun[2]),
               "box_x0": bx0, "box_y0": by0, "box_z0": bz0, "box_x1": bx1, "box_y1": by1, "box_z1": bz1,
               "sunlit_depth_south_m": float(south), "sunlit_depth_north_m": float(north)}
        out[obj.instance_id] = {"sampling_weight": ROW_AND_SUN_WEIGHT / len(tunnels), "plugin": row_and_sun_plugin(),
                                "sun": sun}
    return out
