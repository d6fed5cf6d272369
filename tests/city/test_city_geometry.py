"""Mesh primitives are closed and wound outward; the SAT rectangle test agrees with an
independent linear-programming oracle (is there a point strictly inside both rectangles?)."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from workbench.scene.city import geometry as g


def _signed_volume(v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


def _closed(f):
    """Every directed edge is matched by its reverse exactly once (closed, consistently wound)."""
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    fwd = {tuple(e) for e in edges.tolist()}
    return len(fwd) == len(edges) and all((b, a) in fwd for a, b in fwd)


@pytest.mark.parametrize("part", [
    g.box((0, 0, 0), (2, 3, 4)),
    g.boxes(np.array([[0, 0, 0], [5, 5, 5]]), np.array([[1, 2, 3], [6, 7, 9]])),
    g.cylinder_y(0.3, -0.1, 0.1, (1.0, 0.3)),
    g.ellipsoid((1, 2, 3), (1.0, 0.5, 2.0)),
    g.frustum(0.0, 2.0, (0.5, 0.4), (0.2, 0.1)),
    g.extrude_xz(np.array([[0, 0], [4, 0], [4, 1], [3, 1.5], [0.5, 1.5]]), -0.9, 0.9),
])
def test_solids_closed_and_outward(part):
    v, f = part
    assert _closed(f)
    pieces = 2 if len(f) == 24 and len(v) == 16 else 1
    hull_volume = sum(ConvexHull(v[i * 8:(i + 1) * 8]).volume for i in range(pieces)) \
        if pieces == 2 else ConvexHull(v).volume
    assert _signed_volume(v, f) == pytest.approx(hull_volume, rel=1e-9)


def test_ground_rects_face_up():
    v, f = g.ground_rects(np.array([[0, 0, 2, 1], [5, 5, 6, 9]]), 0.1)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.all(n[:, 2] > 0) and np.allclose(v[:, 2], 0.1)


def test_place_rotates_about_z_then_translates():
    v = np.array([[1.0, 0.0, 0.5]])
    out = g.place(v, 90.0, np.array([10.0, 20.0, 0.0]))
    assert np.allclose(out, [[10.0, 21.0, 0.5]])


def _halfplanes(rect):
    """A x <= b for a counter-clockwise convex polygon."""
    a, b = [], []
    for p, q in zip(rect, np.roll(rect, -1, axis=0)):
        e = q - p
        n = np.array([e[1], -e[0]]) / np.linalg.norm(e)   # outward for CCW
        a.append(n)
        b.append(n @ p)
    return np.array(a), np.array(b)


def _lp_depth(r1, r2):
    """Largest t with a point at least t inside both polygons (negative: separated)."""
    a1, b1 = _halfplanes(r1)
    a2, b2 = _halfplanes(r2)
    a = np.vstack([a1, a2])
    a_ub = np.column_stack([a, np.ones(len(a))])
    res = linprog(c=[0, 0, -1], A_ub=a_ub, b_ub=np.concatenate([b1, b2]),
                  bounds=[(None, None), (None, None), (None, 100)])
    return -res.fun


rect_st = st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(0.2, 6), st.floats(0.2, 4),
                    st.floats(0, 360))


@settings(max_examples=150, deadline=None)
@given(rect_st, rect_st)
def test_sat_matches_lp_oracle(a, b):
    ra, rb = g.oriented_rect(a[:2], *a[2:]), g.oriented_rect(b[:2], *b[2:])
    depth = _lp_depth(ra, rb)
    if abs(depth) < 1e-6:
        return                     # touching: either answer is acceptable
    assert g.rects_overlap(ra, rb) == (depth > 0)
    assert g.rects_overlap(ra, rb) == g.rects_overlap(rb, ra)


def test_sat_margin_and_hard_cases():
    a = g.oriented_rect((0, 0), 4, 2, 0)
    b = g.oriented_rect((4.5, 0), 4, 2, 0)          # 0.5 m gap
    assert not g.rects_overlap(a, b)
    assert g.rects_overlap(a, b, margin_m=0.6)
    # rotated 45°: the bounding boxes overlap but the rectangles do not
    c = g.oriented_rect((1.5, 1.5), 4, 0.5, 135)
    sq = g.oriented_rect((0, 0), 2, 2, 0)
    assert c[:, 0].min() < 1 and c[:, 1].min() < 1        # axis-aligned boxes would collide
    assert not g.rects_overlap(sq, c)
    # one inside the other
    assert g.rects_overlap(g.oriented_rect((0, 0), 10, 10, 0), g.oriented_rect((1, 1), 1, 1, 30))
