"""Detailed pedestrians: a jointed body posed by joint angles, dressed from clothing palettes.

Every body segment (head, neck, torso, pelvis, upper arms, forearms, hands, thighs, shins, feet)
is its own closed convex solid: a tapered tube of elliptic rings between its two joints, with a
rounded cap past each joint so the joint centre lies inside both neighbours (no gaps when bent).
Segment lengths and landmark heights are fractions of stature H after Drillis & Contini (1966,
'Body segment parameters', NYU report 1166-03; as tabulated in Winter, 'Biomechanics and Motor
Control of Human Movement'): hip (greater trochanter) 0.530 H, knee 0.285 H, ankle 0.039 H,
shoulder 0.818 H, elbow 0.630 H, wrist 0.485 H, chin 0.870 H, hand 0.108 H, foot 0.152 H × 0.055 H,
shoulder breadth 0.259 H, hip breadth 0.191 H; the shoulder joint centres are taken 0.20 H
apart and 0.02 H below the acromion, the hip joint centres 0.10 H apart.
Children have larger heads (≈ 1/6 of stature at 1.1 m against ≈ 1/7.7 for adults); the body
below the chin is scaled to fill the rest.

A pose is a small table of angles (degrees, from the vertical, positive forward): hip flexion
of each thigh, knee flexion, foot pitch (toe down positive), shoulder flexion of each upper arm,
elbow flexion, arm abduction and trunk lean. Legs marked `contact` touch the ground: the lowest
one sets the pelvis height, the other rolls onto its toes until it touches too. Walking poses
follow the gait cycle (Perry & Burnfield, 'Gait Analysis'): double support at heel strike
(lead hip ~22° flexed, trailing hip ~15° extended and heel off) and mid-stance (stance leg
vertical, swing knee ~55° flexed), arms swinging opposite to the legs.

Cyclists sit on a city bicycle scaled to their stature (bicycle_points: wheels as tori of tube
pieces, frame tubes, fork, stem, bar, cranks, pedals, saddle): the feet are on the pedals at the
pose's crank angle, the legs reach them by two-link inverse kinematics, and the trunk leans until
the hands reach the bar. The bicycle belongs to the rider's labelled 'pedestrian' instance (one
id, one amodal box around rider and bicycle) — unlike COCO, which labels 'bicycle' separately.
Placement lets cyclists ride along the sidewalk strip (placement.py).

Local frame as every asset: x forward, y left, z up, on the ground, centred on the footprint.
Variant names are deterministic: '<pose>_<index>'; about one in eight is a cyclist.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.stats import norm

from workbench.errors import InvalidValueError
from workbench.scene.city import geometry as g
from workbench.scene.city.assets import Asset, finish_asset
from workbench.scene.city.materials import BOTTOMS, HAIRS, SHOES, SKINS, TOPS

# Drillis & Contini landmark heights and lengths (fractions of stature).
HIP_H, KNEE_H, ANKLE_H, SHOULDER_H, ELBOW_H, WRIST_H, CHIN_H = 0.530, 0.285, 0.039, 0.818, 0.630, 0.485, 0.870
HAND_L, FOOT_L, FOOT_B = 0.108, 0.152, 0.055
SHOULDER_JOINTS_B, SHOULDER_DROP, HIP_JOINTS_B, HIP_B = 0.20, 0.02, 0.10, 0.191
CROTCH_H = 0.470              # bottom of the pelvis segment (crotch height ~ 0.45–0.47 H)
REF_STATURE_M = 1.75          # girths below are for an average adult of this stature


@dataclass(frozen=True)
class Leg:
    hip_deg: float
    knee_deg: float
    foot_pitch_deg: float = 0.0
    contact: bool = True


@dataclass(frozen=True)
class Arm:
    shoulder_deg: float
    elbow_deg: float


@dataclass(frozen=True)
class Pose:
    """Joint angles (deg); legs and arms are (right, left)."""

    name: str
    legs: tuple[Leg, Leg]
    arms: tuple[Arm, Arm]
    trunk_lean_deg: float = 2.0
    arm_abduction_deg: float = 6.0

    def mirrored(self, name: str) -> "Pose":
        return Pose(name, self.legs[::-1], self.arms[::-1], self.trunk_lean_deg, self.arm_abduction_deg)


STANDING = Pose("standing", (Leg(0, 0), Leg(0, 0)), (Arm(0, 10), Arm(0, 10)))
# right heel strike: right leg leads, left leg trails on its toes, left arm forward
WALK_CONTACT = Pose("walk_contact", (Leg(22, 2, -12), Leg(-15, 15, 0)),
                    (Arm(-18, 12), Arm(20, 30)), trunk_lean_deg=4.0)
# right mid-stance: right leg vertical, left leg swinging through, arms passing neutral
WALK_MIDSTANCE = Pose("walk_midstance", (Leg(0, 5), Leg(20, 55, -5, contact=False)),
                      (Arm(3, 15), Arm(-3, 20)), trunk_lean_deg=4.0)
ON_FOOT: tuple[Pose, ...] = (STANDING, WALK_CONTACT, WALK_MIDSTANCE,
                             WALK_CONTACT.mirrored("walk_contact_l"),
                             WALK_MIDSTANCE.mirrored("walk_midstance_l"))


@dataclass(frozen=True)
class Cycling:
    """A rider on a bicycle: crank angle of the right pedal (deg, 0 = forward, 90 = up) and foot
    pitch (toe down); the legs reach the pedals, the trunk leans until the hands reach the bar."""

    name: str
    crank_deg: float
    foot_pitch_deg: float = 12.0


CYCLING: tuple[Cycling, ...] = (Cycling("cycling_power", 0.0), Cycling("cycling_top", 80.0))
POSE_BY_NAME: dict[str, Pose | Cycling] = {p.name: p for p in ON_FOOT + CYCLING}
BIKE_PAINTS = ("paint_black", "paint_silver", "paint_red", "paint_blue", "paint_white", "paint_green")

BUILDS = {"slim": (0.88, 0.85), "average": (1.0, 1.0), "broad": (1.12, 1.18)}   # width, depth factors


@dataclass(frozen=True)
class PedestrianSpec:
    """One detailed pedestrian variant: pose name, stature (m), build and outfit (material names)."""

    name: str
    pose: str
    stature_m: float
    build: str
    top: str
    bottom: str
    shoes: str
    skin: str
    hair: str
    long_sleeves: bool
    shorts: bool
    long_hair: bool
    bike_paint: str | None = None      # frame colour of a cyclist's bicycle


def head_fraction(stature_m: float) -> float:
    """Head height (chin to vertex) as a fraction of stature: 0.13 for adults, up to ~0.17 at 1 m."""
    return 0.13 + 0.04 * float(np.clip((1.55 - stature_m) / 0.55, 0.0, 1.0))


# ---------------------------------------------------------------- skeleton
def _rot_y(v: np.ndarray, deg: float) -> np.ndarray:
    """Rotate about +y so that +x goes down for positive angles (toe down, lean forward)."""
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.stack([v[..., 0] * c + v[..., 2] * s, v[..., 1], -v[..., 0] * s + v[..., 2] * c], -1)


def _down(deg: float, lateral: float = 0.0) -> np.ndarray:
    """Unit vector hanging from the vertical by `deg` forward and tilted `lateral` (sin) sideways."""
    a = np.radians(deg)
    c = np.sqrt(1.0 - lateral ** 2)
    return np.array([np.sin(a) * c, lateral, -np.cos(a) * c])


@dataclass(frozen=True)
class Body:
    """Scaled dimensions of one person (m)."""

    stature: float
    k: float           # scale of Drillis & Contini fractions below the chin
    build_w: float     # build factor across
    build_d: float     # build factor front-to-back

    def L(self, frac: float) -> float:
        """A Drillis & Contini length (fraction of stature) for this body (m)."""
        return frac * self.k * self.stature

    @property
    def W(self) -> float:
        """Scale of girths across (reference-adult girths × this)."""
        return self.stature / REF_STATURE_M * self.build_w

    @property
    def D(self) -> float:
        """Scale of girths front-to-back."""
        return self.stature / REF_STATURE_M * self.build_d


def _body(spec: PedestrianSpec) -> Body:
    return Body(spec.stature_m, (1 - head_fraction(spec.stature_m)) / CHIN_H, *BUILDS[spec.build])


def _foot_points(b: Body) -> np.ndarray:
    """Shoe hull points in the foot frame (origin at the ankle joint, x along the foot)."""
    lf, bf, ha = b.L(FOOT_L), b.L(FOOT_B) * b.build_w, b.L(ANKLE_H)
    sole = -ha
    pts = [(-0.20 * lf, 0.28 * bf, sole), (-0.22 * lf, 0.24 * bf, sole + 0.6 * ha),
           (0.55 * lf, 0.50 * bf, sole), (0.78 * lf, 0.28 * bf, sole),
           (0.74 * lf, 0.24 * bf, sole + 0.45 * ha), (0.40 * lf, 0.40 * bf, sole + 1.05 * ha)]
    pts = [(x, sy * y, z) for x, y, z in pts for sy in (-1, 1)]
    ring = g.ring(0.5 * bf, 0.5 * bf, 0.25 * ha, 8)
    return np.concatenate([np.array(pts), ring])


def _two_link(root: np.ndarray, target: np.ndarray, l1: float, l2: float, bend: np.ndarray) -> np.ndarray:
    """Middle joint of a two-segment chain (lengths l1, l2) from root to target, bent toward
    `bend` (inverse kinematics in the plane of root→target and bend)."""
    d = target - root
    dist = float(np.linalg.norm(d))
    if dist >= l1 + l2 or dist <= abs(l1 - l2):
        raise InvalidValueError(f"limb of {l1:.3f} + {l2:.3f} m cannot reach {dist:.3f} m")
    e = d / dist
    a = (l1 ** 2 - l2 ** 2 + dist ** 2) / (2 * dist)
    n = bend - (bend @ e) * e
    return root + a * e + np.sqrt(l1 ** 2 - a ** 2) * n / np.linalg.norm(n)


def _trunk(lean_deg: float) -> np.ndarray:
    lean = np.radians(lean_deg)
    return np.array([np.sin(lean), 0.0, np.cos(lean)])          # up, leaning forward


def _shoulder(j: dict, b: Body, trunk: np.ndarray, sy: int) -> np.ndarray:
    return j["pelvis"] + (b.L(SHOULDER_H - HIP_H) - b.L(SHOULDER_DROP)) * trunk + \
        np.array([0.0, sy * 0.5 * b.L(SHOULDER_JOINTS_B) * b.build_w, 0.0])


def _upper_body(j: dict, b: Body, trunk: np.ndarray) -> None:
    j["waist"] = j["pelvis"] + b.L(0.06) * trunk
    j["neck"] = j["pelvis"] + b.L(SHOULDER_H - HIP_H) * trunk
    j["chin"] = j["neck"] + np.array([0.0, 0.0, b.L(CHIN_H - SHOULDER_H)])
    for side, sy in (("r", -1), ("l", 1)):
        j[f"shoulder_{side}"] = _shoulder(j, b, trunk, sy)


def _standing_skeleton(pose: Pose, b: Body) -> dict[str, np.ndarray]:
    hip_y = 0.5 * b.L(HIP_JOINTS_B) * b.build_w
    foot = _foot_points(b)
    j: dict[str, np.ndarray] = {}
    pitches = {}
    # legs relative to the pelvis centre at z = 0
    for side, sy, leg in (("r", -1, pose.legs[0]), ("l", 1, pose.legs[1])):
        hip = np.array([0.0, sy * hip_y, 0.0])
        knee = hip + b.L(HIP_H - KNEE_H) * _down(leg.hip_deg)
        ankle = knee + b.L(KNEE_H - ANKLE_H) * _down(leg.hip_deg - leg.knee_deg)
        j[f"hip_{side}"], j[f"knee_{side}"], j[f"ankle_{side}"] = hip, knee, ankle
        pitches[side] = leg.foot_pitch_deg
    sole = {s: j[f"ankle_{s}"][2] + _rot_y(foot, pitches[s])[:, 2].min()
            for s, leg in zip("rl", pose.legs) if leg.contact}
    first = min(sole, key=sole.get)
    ground = sole[first]
    for side in set(sole) - {first}:   # roll onto the toes until this foot touches the ground too
        z = j[f"ankle_{side}"][2]
        lowest = lambda deg: z + _rot_y(foot, deg)[:, 2].min() - ground  # noqa: E731
        if lowest(0.0) < -1e-9:
            raise InvalidValueError(f"pose '{pose.name}': the {side} leg reaches below the ground")
        pitches[side] = brentq(lowest, 0.0, 70.0, xtol=1e-10)
    for key in list(j):
        j[key] = j[key] - np.array([0.0, 0.0, ground])
    j["pelvis"] = np.array([0.0, 0.0, -ground])
    trunk = _trunk(pose.trunk_lean_deg)
    _upper_body(j, b, trunk)
    lat = np.sin(np.radians(pose.arm_abduction_deg))
    for side, sy, arm in (("r", -1, pose.arms[0]), ("l", 1, pose.arms[1])):
        elbow = j[f"shoulder_{side}"] + b.L(SHOULDER_H - SHOULDER_DROP - ELBOW_H) * _down(arm.shoulder_deg, sy * lat)
        j[f"elbow_{side}"] = elbow
        j[f"wrist_{side}"] = elbow + b.L(ELBOW_H - WRIST_H) * _down(arm.shoulder_deg + arm.elbow_deg, sy * lat)
        j[f"foot_pitch_{side}"] = np.array([pitches[side]])
    return j


def _cycling_skeleton(pose: "Cycling", b: Body) -> dict[str, np.ndarray]:
    bike = bicycle_points(b)
    j: dict[str, np.ndarray] = {k: v.copy() for k, v in bike.items()}
    hip_y = 0.5 * b.L(HIP_JOINTS_B) * b.build_w
    j["pelvis"] = bike["saddle"] + np.array([0.03, 0.0, 0.07]) * b.D
    ball = np.array([0.55 * b.L(FOOT_L), 0.0, -b.L(ANKLE_H)])     # sole under the ball of the foot
    l_thigh, l_shin = b.L(HIP_H - KNEE_H), b.L(KNEE_H - ANKLE_H)
    for side, sy, crank in (("r", -1, pose.crank_deg), ("l", 1, pose.crank_deg + 180.0)):
        c = np.radians(crank)
        pedal = bike["bb"] + bike["crank_m"] * np.array([np.cos(c), 0.0, np.sin(c)])
        pedal[1] = sy * hip_y
        hip = j["pelvis"] + np.array([0.0, sy * hip_y, 0.0])
        ankle = pedal - _rot_y(ball, pose.foot_pitch_deg)
        j[f"pedal_{side}"], j[f"hip_{side}"], j[f"ankle_{side}"] = pedal, hip, ankle
        j[f"knee_{side}"] = _two_link(hip, ankle, l_thigh, l_shin, np.array([1.0, 0.0, 0.0]))
        j[f"foot_pitch_{side}"] = np.array([pose.foot_pitch_deg])
    l_upper, l_fore = b.L(SHOULDER_H - SHOULDER_DROP - ELBOW_H), b.L(ELBOW_H - WRIST_H)
    grip = bike["grip_r"] + np.array([-0.02, 0.0, 0.02]) * b.D       # wrist just behind the bar

    def slack(lean_deg):           # lean forward until the elbows are bent by ~20 % of the reach
        return np.linalg.norm(grip - _shoulder(j, b, _trunk(lean_deg), -1)) - 0.9 * (l_upper + l_fore)

    trunk = _trunk(brentq(slack, 0.0, 80.0, xtol=1e-8))
    _upper_body(j, b, trunk)
    for side, sy in (("r", -1), ("l", 1)):
        wrist = bike[f"grip_{side}"] + np.array([-0.02, 0.0, 0.02]) * b.D
        j[f"wrist_{side}"] = wrist
        j[f"elbow_{side}"] = _two_link(j[f"shoulder_{side}"], wrist, l_upper, l_fore,
                                       np.array([-0.2, sy * 0.6, -1.0]))
    return j


def skeleton(spec: PedestrianSpec) -> dict[str, np.ndarray]:
    """Joint centres (m, body frame: ground z = 0) of a posed person: 'hip_r', 'knee_r',
    'ankle_r', 'shoulder_r', 'elbow_r', 'wrist_r' (and '_l'), 'pelvis', 'waist', 'neck' (base),
    'chin', 'foot_pitch_r/_l' (deg, as 1-element arrays); a cyclist also has the bicycle's
    points (bicycle_points) and 'pedal_r/_l'."""
    pose, b = POSE_BY_NAME[spec.pose], _body(spec)
    if isinstance(pose, Cycling):
        return _cycling_skeleton(pose, b)
    return _standing_skeleton(pose, b)


# ---------------------------------------------------------------- bicycle
# A city / hybrid bicycle for a 1.75 m rider (m): 700C wheels (622 mm rim + 35 mm tyres), 1.06 m
# wheelbase, 73° seat and 71° head angles, 170 mm cranks, 0.58 m bar; saddle height (bottom
# bracket to saddle top) 0.883 × inseam (LeMond's rule), inseam taken as 0.45 H; the bar 0.10 m
# above the saddle (upright riding). Every length scales with the rider's stature (children
# get 20–24" wheels).
WHEEL_R, TYRE_R, REAR_X, FRONT_X, BB_Z, CRANK = 0.346, 0.018, -0.43, 0.63, 0.28, 0.17
SEAT_DEG, HEAD_DEG, FORK, BAR_HALF, BAR_RISE, INSEAM_H = 73.0, 71.0, 0.40, 0.29, 0.10, 0.45


def bicycle_points(b: Body) -> dict[str, np.ndarray]:
    """Key points of the rider's bicycle (m, x forward from the bottom bracket, ground z = 0)."""
    s = b.stature / REF_STATURE_M
    rear, front = np.array([REAR_X * s, 0, WHEEL_R * s]), np.array([FRONT_X * s, 0, WHEEL_R * s])
    bb = np.array([0.0, 0.0, BB_Z * s])
    seat_dir = np.array([-np.cos(np.radians(SEAT_DEG)), 0.0, np.sin(np.radians(SEAT_DEG))])
    head_dir = np.array([-np.cos(np.radians(HEAD_DEG)), 0.0, np.sin(np.radians(HEAD_DEG))])
    saddle = bb + 0.883 * INSEAM_H * b.k * b.stature * seat_dir
    bar_z = saddle[2] + BAR_RISE * s
    bar = front + (bar_z - front[2]) / head_dir[2] * head_dir
    lateral = np.array([0.0, BAR_HALF * s, 0.0])
    return {"rear_axle": rear, "front_axle": front, "bb": bb, "saddle": saddle,
            "seat_cluster": bb + 0.62 * (saddle - bb), "head_bottom": front + FORK * s * head_dir,
            "head_top": front + (FORK + 0.16) * s * head_dir, "bar": bar,
            "grip_r": bar - lateral + np.array([-0.05 * s, 0, 0]), "grip_l": bar + lateral + np.array([-0.05 * s, 0, 0]),
            "crank_m": np.float64(CRANK * s)}


def _wheel(center: np.ndarray, radius: float, tube: float, n: int = 12) -> g.Part:
    """A tyre: a torus in the x–z plane made of n overlapping convex tube pieces."""
    r = radius - tube
    pieces = []
    for k in range(n):
        a0, a1 = 2 * np.pi * (k - 0.08) / n, 2 * np.pi * (k + 1.08) / n
        p0 = center + r * np.array([np.cos(a0), 0.0, np.sin(a0)])
        p1 = center + r * np.array([np.cos(a1), 0.0, np.sin(a1)])
        pieces.append(_tube(p0, p1, [(0.0, tube, tube), (1.0, tube, tube)], n=5))
    return g.merge(pieces)


def bicycle_parts(spec: PedestrianSpec, j: dict[str, np.ndarray]) -> dict[str, tuple[str, g.Part]]:
    """The bicycle of a cyclist: tyres, hubs, frame tubes, fork, stem, bar, cranks, pedals, saddle."""
    s = spec.stature_m / REF_STATURE_M
    tr = 0.014 * s
    y = np.array([0.0, 1.0, 0.0])

    def rod(p, q, r=tr):
        return _tube(p, q, [(0.0, r, r), (1.0, r, r)], n=6)

    stays = [rod(j["bb"] + sy * 0.06 * s * y, j["rear_axle"] + sy * 0.065 * s * y, 0.8 * tr) for sy in (-1, 1)]
    stays += [rod(j["seat_cluster"], j["rear_axle"] + sy * 0.065 * s * y, 0.7 * tr) for sy in (-1, 1)]
    frame = [rod(j["bb"], j["seat_cluster"], 1.1 * tr), rod(j["bb"], j["head_bottom"], 1.2 * tr),
             rod(j["seat_cluster"], j["head_top"]), rod(j["head_bottom"], j["head_top"], 1.3 * tr),
             rod(j["front_axle"], j["head_bottom"], 0.9 * tr)] + stays
    metal = [rod(j["seat_cluster"], j["saddle"], 0.8 * tr), rod(j["head_top"], j["bar"], 0.9 * tr),
             rod(j["grip_r"] - 0.04 * s * y, j["grip_l"] + 0.04 * s * y, 0.8 * tr)]
    metal += [rod(j["rear_axle"] - 0.07 * s * y, j["rear_axle"] + 0.07 * s * y, 1.5 * tr),
              rod(j["front_axle"] - 0.06 * s * y, j["front_axle"] + 0.06 * s * y, 1.5 * tr)]
    for side, sy in (("r", -1), ("l", 1)):
        pedal = j[f"pedal_{side}"]
        arm_root = j["bb"] + sy * 0.07 * s * y
        metal.append(rod(arm_root, pedal - sy * 0.03 * s * y, 0.9 * tr))
        metal.append(g.box(tuple(pedal - np.array([0.045, 0.05, 0.022]) * s),
                           tuple(pedal + np.array([0.045, 0.05, -0.004]) * s)))
    tyres = [_wheel(j[k], WHEEL_R * s, TYRE_R * s) for k in ("rear_axle", "front_axle")]
    saddle = g.ellipsoid(tuple(j["saddle"] + np.array([0.0, 0.0, -0.02 * s])), (0.13 * s, 0.075 * s, 0.03 * s), 4, 8)
    return {"bike_frame": (spec.bike_paint, g.merge(frame)), "bike_metal": ("metal_dark", g.merge(metal)),
            "bike_tyres": ("rubber", g.merge(tyres)), "bike_saddle": ("plastic_black", saddle)}


# ---------------------------------------------------------------- solids
def _tube(p: np.ndarray, q: np.ndarray, rings: list[tuple[float, float, float]], n: int = 8) -> g.Part:
    """Convex tube from p to q: rings (t, r_sagittal, r_lateral) at p + t·(q − p) (t may be < 0
    or > 1 for caps past a joint), each perpendicular to the axis."""
    axis = q - p
    a = axis / np.linalg.norm(axis)
    ref = np.array([0.0, 1.0, 0.0]) if abs(a[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    v = ref - (ref @ a) * a
    v /= np.linalg.norm(v)
    u = np.cross(v, a)
    t = 2 * np.pi * (np.arange(n) + 0.5) / n
    pts = [p + tt * axis + rx * np.cos(t)[:, None] * u + ry * np.sin(t)[:, None] * v
           for tt, rx, ry in rings]
    return g.convex_solid(np.concatenate(pts))


def _limb(p, q, r0: tuple[float, float], r1: tuple[float, float], mid=None, n=8) -> g.Part:
    """Tapered limb between joints p and q (radii (sagittal, lateral) there), with rounded caps."""
    length = np.linalg.norm(q - p)
    c0, c1 = 0.55 * max(r0) / length, 0.55 * max(r1) / length
    rings = [(-c0, 0.6 * r0[0], 0.6 * r0[1]), (0.0, *r0)]
    if mid is not None:
        rings.append(mid)
    rings += [(1.0, *r1), (1.0 + c1, 0.6 * r1[0], 0.6 * r1[1])]
    return _tube(p, q, rings, n)


def body_parts(spec: PedestrianSpec) -> dict[str, tuple[str, g.Part]]:
    """Every segment of a posed, dressed person: name → (material, closed solid), body frame."""
    b, j = _body(spec), skeleton(spec)
    W, D, H = b.W, b.D, spec.stature_m
    out: dict[str, tuple[str, g.Part]] = {}
    foot = _foot_points(b)
    legwear = spec.skin if spec.shorts else spec.bottom
    forearm = spec.top if spec.long_sleeves else spec.skin
    for s in "rl":
        hip, knee, ankle = j[f"hip_{s}"], j[f"knee_{s}"], j[f"ankle_{s}"]
        out[f"thigh_{s}"] = (spec.bottom, _limb(hip, knee, (0.085 * D, 0.080 * W), (0.056 * D, 0.054 * W),
                                                (0.3, 0.080 * D, 0.076 * W)))
        out[f"shin_{s}"] = (legwear, _limb(knee, ankle, (0.052 * D, 0.050 * W), (0.036 * D, 0.034 * W),
                                           (0.3, 0.056 * D, 0.050 * W)))
        out[f"foot_{s}"] = (spec.shoes, g.convex_solid(ankle + _rot_y(foot, j[f"foot_pitch_{s}"][0])))
        sh, el, wr = j[f"shoulder_{s}"], j[f"elbow_{s}"], j[f"wrist_{s}"]
        out[f"upper_arm_{s}"] = (spec.top, _limb(sh, el, (0.050 * D, 0.048 * W), (0.038 * D, 0.036 * W)))
        out[f"forearm_{s}"] = (forearm, _limb(el, wr, (0.037 * D, 0.035 * W), (0.027 * D, 0.022 * W)))
        d = (wr - el) / np.linalg.norm(wr - el)
        tip = wr + b.L(HAND_L) * 0.8 * d
        out[f"hand_{s}"] = (spec.skin, _tube(wr, tip, [(-0.15, 0.024 * D, 0.018 * W), (0.0, 0.030 * D, 0.020 * W),
                                                      (0.5, 0.045 * D, 0.018 * W), (1.0, 0.030 * D, 0.013 * W)]))
    pel, neck = j["pelvis"], j["neck"]
    trunk = (neck - pel) / np.linalg.norm(neck - pel)
    hip_half = 0.5 * b.L(HIP_B) * b.build_w
    down = pel - b.L(HIP_H - CROTCH_H) * trunk
    out["pelvis"] = (spec.bottom, _tube(down, pel + b.L(0.07) * trunk,
                                        [(0.0, 0.09 * D, 0.75 * hip_half), (0.45, 0.11 * D, hip_half),
                                         (1.0, 0.10 * D, 0.88 * hip_half)], n=12))
    sh_half = 0.5 * b.L(SHOULDER_JOINTS_B) * b.build_w
    t_len = np.linalg.norm(neck - pel)
    out["torso"] = (spec.top, _tube(pel, neck, [
        (b.L(0.05) / t_len, 0.10 * D, 0.85 * hip_half), (b.L(0.19) / t_len, 0.125 * D, sh_half + 0.01 * W),
        (1.0 - b.L(SHOULDER_DROP) / t_len, 0.10 * D, sh_half + 0.035 * W),
        (1.0 + b.L(0.01) / t_len, 0.07 * D, 0.6 * sh_half)], n=12))
    chin = j["chin"]
    out["neck"] = (spec.skin, _limb(neck - np.array([0, 0, 0.02]), chin, (0.055 * D, 0.055 * W),
                                    (0.048 * D, 0.048 * W)))
    rz = 0.5 * head_fraction(H) * H                 # head half-height: vertex = chin + 2 rz
    c = chin + np.array([0.012 * D, 0.0, 0.95 * rz])
    out["head"] = (spec.skin, g.ellipsoid(tuple(c), (0.100 * D, 0.078 * W, 0.98 * rz), 7, 12))
    hair = [g.ellipsoid(tuple(c + np.array([-0.012 * D, 0, 0.30 * rz])), (0.104 * D, 0.083 * W, 0.75 * rz), 5, 12)]
    if spec.long_hair:
        hair.append(g.ellipsoid(tuple(c + np.array([-0.05 * D, 0, -0.35 * rz])),
                                (0.06 * D, 0.085 * W, 0.9 * rz), 4, 10))
    out["hair"] = (spec.hair, g.merge(hair))
    if isinstance(POSE_BY_NAME[spec.pose], Cycling):
        out.update(bicycle_parts(spec, j))
    return out


def _pedestrian(spec: PedestrianSpec) -> Asset:
    parts: dict[str, list[g.Part]] = {}
    for material, part in body_parts(spec).values():
        parts.setdefault(material, []).append(part)
    return finish_asset("pedestrian", spec.name, parts)


# ---------------------------------------------------------------- variants
N_VARIANTS = 80
CHILD_STATURES_M = (1.02, 1.15, 1.28, 1.40)
# adult stature (m): women ~1.63 ± 0.07, men ~1.77 ± 0.07 (roughly European adults, NCD-RisC 2016)
ADULT_STATURE_M = ((1.63, 0.07), (1.77, 0.07))


def _specs() -> tuple[PedestrianSpec, ...]:
    builds = tuple(BUILDS)
    out = []
    for i in range(N_VARIANTS):
        cyclist = i % 8 == 6
        pose = CYCLING[(i // 8) % len(CYCLING)].name if cyclist else ON_FOOT[i % len(ON_FOOT)].name
        if i % 9 == 4:
            h = CHILD_STATURES_M[(i // 9) % len(CHILD_STATURES_M)]
        else:
            mean, sd = ADULT_STATURE_M[(i // len(ON_FOOT)) % 2]
            u = (0.5 + i * 0.6180339887) % 1.0
            h = float(np.clip(mean + sd * norm.ppf(0.03 + 0.94 * u), 1.45, 1.95))
        out.append(PedestrianSpec(
            f"{pose}_{i:02d}", pose, round(h, 3), builds[(i * 5 // 3) % 3],
            TOPS[(i * 7) % len(TOPS)], BOTTOMS[(i * 3 + i // 8) % len(BOTTOMS)],
            SHOES[(i * 2 + i // 5) % len(SHOES)], SKINS[(i + i // 3) % len(SKINS)],
            HAIRS[(i * 3 + i // 4) % len(HAIRS)], long_sleeves=(i * 5) % 7 < 4,
            shorts=(i * 3) % 11 == 1, long_hair=(i * 7) % 5 < 2,
            bike_paint=BIKE_PAINTS[(i // 8) % len(BIKE_PAINTS)] if cyclist else None))
    return tuple(out)


PEDESTRIAN_SPECS = _specs()
DETAILED_PEDESTRIANS: dict[str, tuple] = {s.name: (_pedestrian, s) for s in PEDESTRIAN_SPECS}
CYCLISTS = frozenset(s.name for s in PEDESTRIAN_SPECS if s.bike_paint is not None)
