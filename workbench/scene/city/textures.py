"""Seeded, tileable scalar textures in [0, 1] (numpy): the blend weights of procedural surfaces.

Every texture is periodic over its own array (the noise lattice wraps), so a renderer can repeat
it ('repeat' wrap mode) without seams. The same (kind, size, seed, fraction, strength) always
gives the same array, bit for bit.

- Value noise: random values on a periodic lattice, quintic-faded bilinear interpolation;
  fBm sums octaves of doubling frequency and halving amplitude (normalised by the amplitude sum,
  so it stays in [0, 1]).
- Coverage masks (puddles, soil patches): fBm above its (1 − fraction) quantile, with a soft
  edge, so the mask covers ≈ `fraction` of the area.
- Cracks: thin lines along an fBm iso-contour (the median level): wiggly, branching networks.
- Slab joints: a 1 cm joint along two edges of a square tile (one slab or panel per tile).
- Brick: running bond of 215 × 65 mm bricks with 10 mm joints (UK format), one random value
  per brick.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError

KINDS = ("asphalt_wear", "puddles", "stains", "streaks", "soil_patches", "brick_mortar", "brick_variation",
         "slab_joints")
BRICK_M = (0.215, 0.065)        # brick length × height (m), UK format
JOINT_M = 0.010                 # mortar joint (m)
BRICKS_PER_TILE = (8, 24)       # running-bond tile: 8 bricks along, 24 courses up → 1.8 × 1.8 m
BRICK_TILE_M = (BRICKS_PER_TILE[0] * (BRICK_M[0] + JOINT_M), BRICKS_PER_TILE[1] * (BRICK_M[1] + JOINT_M))
SLAB_M = 1.5                    # concrete slab / panel module (m); one slab per slab_joints tile


def _fade(t: np.ndarray) -> np.ndarray:
    return t * t * t * (t * (t * 6 - 15) + 10)


def value_noise(shape_px: tuple[int, int], cells: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
    """Periodic value noise on an H×W grid with cells[0]×cells[1] lattice cells (rows, columns)."""
    h, w = shape_px
    lattice = rng.random(cells)
    y = np.arange(h) * (cells[0] / h)
    x = np.arange(w) * (cells[1] / w)
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
    fy, fx = _fade(y - y0)[:, None], _fade(x - x0)[None, :]
    y1, x1 = (y0 + 1) % cells[0], (x0 + 1) % cells[1]
    a, b = lattice[np.ix_(y0, x0)], lattice[np.ix_(y0, x1)]
    c, d = lattice[np.ix_(y1, x0)], lattice[np.ix_(y1, x1)]
    return (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy


def fbm(shape_px: tuple[int, int], cells: tuple[int, int], octaves: int, rng: np.random.Generator,
        gain: float = 0.5) -> np.ndarray:
    """Fractional Brownian motion: `octaves` of value noise from `cells` up, doubling each time."""
    total, amp, norm = np.zeros(shape_px), 1.0, 0.0
    for k in range(octaves):
        c = (min(cells[0] << k, shape_px[0]), min(cells[1] << k, shape_px[1]))
        total += amp * value_noise(shape_px, c, rng)
        norm += amp
        amp *= gain
    return total / norm


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def coverage(field: np.ndarray, fraction: float, softness: float = 0.03) -> np.ndarray:
    """Soft mask where `field` is above its (1 − fraction) quantile: ≈ `fraction` of the area."""
    if fraction <= 0:
        return np.zeros_like(field)
    q = float(np.quantile(field, 1.0 - fraction))
    return smoothstep(q - softness, q + softness, field)


def cracks(field: np.ndarray, width: float) -> np.ndarray:
    """1 on thin lines along the median iso-contour of `field`, 0 elsewhere."""
    return 1.0 - smoothstep(0.0, width, np.abs(field - np.median(field)))


def brick_bond(size_px: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(mortar mask, per-brick value) of a square running-bond tile, both in [0, 1]."""
    nx, ny = BRICKS_PER_TILE
    v = (np.arange(size_px) + 0.5) / size_px * ny                 # courses (rows)
    course = np.floor(v).astype(int)
    u = (np.arange(size_px) + 0.5)[None, :] / size_px * nx + 0.5 * (course % 2)[:, None]
    brick = np.floor(u).astype(int) % nx
    du = (u - np.floor(u)) * (BRICK_M[0] + JOINT_M)                # metres into the brick module
    dv = ((v - course) * (BRICK_M[1] + JOINT_M))[:, None]
    mortar = ((du < JOINT_M) | (dv < JOINT_M)).astype(np.float64)
    per_brick = rng.random((ny, nx))
    return mortar, per_brick[course[:, None], brick]


@lru_cache(maxsize=64)
def bake(kind: str, size_px: int, seed: int, fraction: float = 0.0, strength: float = 1.0) -> np.ndarray:
    """A size_px × size_px float32 texture of `kind` (KINDS) in [0, strength] (read-only)."""
    if kind not in KINDS:
        raise InvalidValueError(f"unknown texture kind '{kind}'; known: {', '.join(KINDS)}")
    if not 16 <= size_px <= 4096:
        raise InvalidValueError(f"texture size must be 16…4096 px, got {size_px}")
    rng = np.random.default_rng([seed, KINDS.index(kind)])
    shape = (size_px, size_px)
    if kind == "asphalt_wear":
        # Aged (1) vs fresh (0) binder: fBm wear, fresh rectangular repair patches, dark cracks.
        wear = smoothstep(0.3, 0.7, fbm(shape, (4, 4), 6, rng))
        patches = np.zeros(shape)
        for _ in range(3):
            y, x = rng.integers(0, size_px, 2)
            hh, ww = rng.integers(size_px // 16, size_px // 5, 2)
            patches[np.ix_(np.arange(y, y + hh) % size_px, np.arange(x, x + ww) % size_px)] = 1.0
        crack = cracks(fbm(shape, (3, 3), 5, rng), 0.006)
        w = wear * (1 - patches) * (1 - crack)
    elif kind == "puddles":
        w = coverage(fbm(shape, (3, 3), 5, rng), fraction)
    elif kind == "soil_patches":
        w = coverage(fbm(shape, (4, 4), 6, rng), fraction, softness=0.05)
    elif kind == "stains":
        w = smoothstep(0.45, 0.8, fbm(shape, (4, 4), 6, rng))
    elif kind == "slab_joints":
        edge = (np.arange(size_px) + 0.5) / size_px * SLAB_M < JOINT_M
        w = (edge[:, None] | edge[None, :]).astype(np.float64)
    elif kind == "streaks":
        # Rain-washed soiling: noise stretched 8× vertically (rows = height up the wall).
        w = smoothstep(0.4, 0.8, fbm(shape, (2, 16), 5, rng))
    else:
        mortar, per_brick = brick_bond(size_px, np.random.default_rng([seed, KINDS.index("brick_mortar")]))
        w = mortar if kind == "brick_mortar" else per_brick
    out = (strength * np.clip(w, 0.0, 1.0)).astype(np.float32)
    out.setflags(write=False)
    return out
