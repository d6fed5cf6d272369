"""Car paint seen second-hand inside a tunnel by day: its clear coat is as sharp as the camera
sees it, and rougher for every other ray (path regularization).

Inside a tunnel by day a car's clear coat (GGX α = 0.02, scene_builder.PAINT_COAT_ALPHA) is a
near-mirror of the sunlit street beyond the exit, 10²–10³× brighter than the interior. The
ceiling and walls see that mirror image only through a diffuse bounce that must land where the
coat's narrow lobe happens to point out of the exit, so a path tracer finds it rarely and weighs it
heavily: white dots. Traced vertex by vertex on city_tunnel frame 1 (376×240, 160 one-sample
renders; samples over 100× their pixel's mean, luminaire-lens edge hits left aside), 61 of 96 were
ceiling → car coat → sunlit façade (sun found by next-event estimation); no other kind came near.

`CameraSharpCoat` holds two coats, the sharp one and a rough twin (α = REGULARIZED_ALPHA). A ray
that left the camera (its origin, si.p + t·ω_i, within CAMERA_RADIUS_M of the camera: the pinhole
and a lens's aperture lie well inside) meets the sharp coat, as do all rays outside the tunnels'
boxes; other rays inside a box meet the rough one. The camera's view of cars, with every glint and
reflection of the exit, is unchanged; the light cars throw onto the tunnel is blurred over a wider
lobe. This is biased (Kaplanyan & Dachsbacher 2013 regularize the same way, shrinking the
roughening with the sample count; production renderers' "filter glossy" does it with a fixed
one): the bias is the difference between the two coats' reflection of the light around them.
Both coats report their own pdf, so next-event estimation and BSDF sampling stay consistent at
each vertex.

Measured on city_tunnel frame 1 (376×240, 128 one-sample renders, the same seeds each; pixels
away from the luminaires and the bright exit): pixels whose samples' relative variance exceeds 20
(one sample holding about half the pixel's light) 105 with the sharp coat → 72 / 49 / 17 with the
rough twin at α 0.05 / 0.1 / 0.2; the frame's mean −0.08 / −0.19 / −0.36 %, the worst 40 × 94
pixel tile −0.3 / −0.6 / −1.0 % (standard error ~0.3 %); CPU 63.4 → 64.4 s for the 128 renders at
α 0.2 (beside other work). α 0.2 is used:
the bias stays far below the sensor's shot noise. In the test scene built to show it (a ceiling lit
only by a small lamp's mirror image in a coat) the rough twin throws 15 % less light (Mitsuba's
roughplastic loses energy as α grows) and cuts the per-estimate variance 24×.

A scene whose camera moves after loading (city_frame.CitySceneSession) calls `point_coats_at`.
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render.portal_guide import inside_tunnel
from workbench.render.switch import Switch

REGULARIZED_ALPHA = 0.2     # the rough twin's GGX α (the sharp coat's is 0.02)
CAMERA_RADIUS_M = 0.25      # a ray whose origin lies this close to the camera came from it
_CLASSES: dict[str, type] = {}
_SWITCH = Switch()          # off only inside sharp_coats(): the benchmark's 'before'


def regularizing() -> bool:
    """Whether scenes built now regularize their coats (not inside sharp_coats())."""
    return _SWITCH.on


def sharp_coats():
    """Scenes built inside the block keep every ray's coat sharp: the render-noise benchmark's
    'before'."""
    return _SWITCH.off()


def _coat_class():
    """The CameraSharpCoat BSDF class for the current Mitsuba variant (made once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _CLASSES:
        return _CLASSES[variant]

    class CameraSharpCoat(mi.BSDF):
        """The sharp coat for camera rays and outside the boxes, the rough twin for other rays
        inside them (module docstring)."""

        def __init__(self, props, sharp, rough, boxes_m, origin_m):
            mi.BSDF.__init__(self, props)
            self.sharp, self.rough, self.boxes = sharp, rough, boxes_m
            self.point_at(origin_m)
            self.m_flags = sharp.flags() | rough.flags()
            self.m_components = [sharp.flags(i) for i in range(sharp.component_count())]

        def point_at(self, origin_m):
            """The camera's position (m) after it moved."""
            self.origin = mi.Point3f(*(float(v) for v in origin_m))
            dr.make_opaque(self.origin)

        def _rough(self, si):
            came_from = si.p + si.to_world(si.wi) * si.t
            from_camera = dr.squared_norm(came_from - self.origin) < CAMERA_RADIUS_M ** 2
            inside = mi.Bool(False)
            for box in self.boxes:
                inside |= inside_tunnel(si.p, box)
            return inside & ~from_camera

        def sample(self, ctx, si, sample1, sample2, active=True):
            rough = self._rough(si)
            bs_s, w_s = self.sharp.sample(ctx, si, sample1, sample2, active & ~rough)
            bs_r, w_r = self.rough.sample(ctx, si, sample1, sample2, active & rough)
            return dr.select(rough, bs_r, bs_s), dr.select(rough, w_r, w_s)

        def eval(self, ctx, si, wo, active=True):
            rough = self._rough(si)
            return dr.select(rough, self.rough.eval(ctx, si, wo, active & rough),
                             self.sharp.eval(ctx, si, wo, active & ~rough))

        def pdf(self, ctx, si, wo, active=True):
            rough = self._rough(si)
            return dr.select(rough, self.rough.pdf(ctx, si, wo, active & rough),
                             self.sharp.pdf(ctx, si, wo, active & ~rough))

        def eval_pdf(self, ctx, si, wo, active=True):
            rough = self._rough(si)
            v_r, p_r = self.rough.eval_pdf(ctx, si, wo, active & rough)
            v_s, p_s = self.sharp.eval_pdf(ctx, si, wo, active & ~rough)
            return dr.select(rough, v_r, v_s), dr.select(rough, p_r, p_s)

        def eval_diffuse_reflectance(self, si, active=True):
            return self.sharp.eval_diffuse_reflectance(si, active)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"CameraSharpCoat[{self.sharp}, rough {self.rough}]"

    _CLASSES[variant] = CameraSharpCoat
    return CameraSharpCoat


def camera_sharp_coat(sharp, rough, boxes_m, origin_m) -> object:
    """`sharp` (a loaded Mitsuba BSDF) for rays from the camera at origin_m (m) and everywhere
    outside boxes_m (((x0, y0, z0), (x1, y1, z1)), m: the tunnels' interiors), `rough` for the
    other rays inside them."""
    import mitsuba as mi

    boxes = []
    for box in boxes_m:
        lo, hi = (np.asarray(b, dtype=np.float64) for b in box)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(np.r_[lo, hi])) or np.any(hi <= lo):
            raise InvalidValueError(f"a regularization box must be two finite 3-vectors with min < max, got {box}")
        boxes.append((tuple(lo.tolist()), tuple(hi.tolist())))
    origin = np.asarray(origin_m, dtype=np.float64)
    if origin.shape != (3,) or not np.all(np.isfinite(origin)):
        raise InvalidValueError(f"the camera's position must be a finite 3-vector (m), got {origin_m}")
    return _coat_class()(mi.Properties(), sharp, rough, boxes, origin.tolist())


def point_coats_at(mi_scene, origin_m) -> int:
    """Tell every CameraSharpCoat of a loaded scene (inside portal guides too) where the camera
    now is; returns how many there were."""
    import mitsuba as mi

    cls = _CLASSES.get(mi.variant())
    if cls is None:
        return 0
    seen = set()
    for shape in mi_scene.shapes():
        bsdf = shape.bsdf()
        while bsdf is not None and not isinstance(bsdf, cls):
            bsdf = getattr(bsdf, "nested", None)
        if bsdf is not None and id(bsdf) not in seen:
            seen.add(id(bsdf))
            bsdf.point_at(origin_m)
    return len(seen)
