"""No two objects interpenetrate in 3-D: every convex piece of every placed object and building
(mesh connected components) is checked against the pieces of other objects — z ranges that
overlap and 2-D convex hulls that overlap (depth by linear programming) would be a collision.
Independent of the placement code's own footprint bookkeeping."""
import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError

from workbench.scene.city import CityRecipe, TunnelParams, generate_city

TOL_M = 0.01
SOLID = ("car", "bus", "truck", "pedestrian", "tree", "lamp", "bench", "mailbox", "building", "tunnel")


def _pieces(city):
    out = []   # (object id, zmin, zmax, hull equations (K×3), xy bbox)
    for o in city.objects:
        if o.class_name not in SOLID:
            continue
        for m in o.meshes:
            if m.material == "glass_dark" and o.class_name == "building":
                continue                               # window panes sit on the facade
            n = len(m.vertices)
            f = m.faces
            adj = coo_matrix((np.ones(3 * len(f)), (np.r_[f[:, 0], f[:, 1], f[:, 2]],
                                                    np.r_[f[:, 1], f[:, 2], f[:, 0]])), shape=(n, n))
            k, label = connected_components(adj, directed=False)
            for c in range(k):
                v = m.vertices[label == c]
                try:
                    hull = ConvexHull(v[:, :2])
                except QhullError:
                    continue                           # a vertical quad: no area in plan
                out.append((o.instance_id, v[:, 2].min(), v[:, 2].max(), hull.equations,
                            np.r_[v[:, :2].min(0), v[:, :2].max(0)]))
    return out


def _depth(e1, e2):
    a = np.vstack([e1[:, :2], e2[:, :2]])
    b = -np.concatenate([e1[:, 2], e2[:, 2]])
    res = linprog([0, 0, -1], A_ub=np.column_stack([a, np.ones(len(a))]), b_ub=b,
                  bounds=[(None, None), (None, None), (None, 10)])
    return -res.fun


@pytest.mark.parametrize("seed,detail,tunnel,parked", [
    (0, "simple", None, 0), (7, "simple", None, 0), (3, "detailed", None, 24),
    (5, "simple", TunnelParams(street_index=1, length_m=84.0), 24)])
def test_no_interpenetration(seed, detail, tunnel, parked):
    """(With a tunnel: trees and lamps stay out from under its roof, vehicles and people fit inside;
    parked cars stand clear of everything at the kerb.)"""
    city = generate_city(CityRecipe(seed=seed, arrangement=seed, n_cars=24, n_pedestrians=40,
                                    n_parked_cars=parked, asset_detail=detail, tunnel=tunnel))
    pieces = _pieces(city)
    ids = np.array([p[0] for p in pieces])
    z = np.array([[p[1], p[2]] for p in pieces])
    bb = np.array([p[4] for p in pieces])
    cand = ((ids[:, None] != ids[None]) &
            (z[:, None, 0] < z[None, :, 1] - TOL_M) & (z[None, :, 0] < z[:, None, 1] - TOL_M) &
            (bb[:, None, 0] < bb[None, :, 2] - TOL_M) & (bb[None, :, 0] < bb[:, None, 2] - TOL_M) &
            (bb[:, None, 1] < bb[None, :, 3] - TOL_M) & (bb[None, :, 1] < bb[:, None, 3] - TOL_M))
    i, j = np.nonzero(np.triu(cand))
    clashes = [(ids[a], ids[b]) for a, b in zip(i, j) if _depth(pieces[a][3], pieces[b][3]) > TOL_M]
    assert not clashes, f"interpenetrating objects (instance ids): {clashes[:5]}"
