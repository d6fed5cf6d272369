"""Reverse ray tracing through a workbench Lens as Dr.Jit expressions (the lens camera's kernel).

The same vertex-relative intersection and Snell refraction as workbench.optics.lens.trace, written
with Dr.Jit arithmetic so Mitsuba compiles it into the camera's ray-generation kernel. Each lens
constant is a Python float (it becomes a kernel literal); `dr` and `mi` are the drjit and mitsuba
modules of the current variant, passed in so importing this module needs neither.
"""
from __future__ import annotations

from workbench.errors import InvalidValueError
from workbench.optics.lens.glass import Material
from workbench.optics.lens.model import Lens


def index_expr(mat: Material, wl, dr, mi):
    """Refractive index as a Dr.Jit expression of wavelength `wl` (nm), or a Python float."""
    if mat.kind == "constant":
        return float(mat.nd)
    lam_um = wl * 1e-3
    if mat.kind == "abbe":
        A, B = mat.cauchy_coefficients()
        return float(A) + float(B) / (lam_um * lam_um)
    if mat.kind == "sellmeier":
        l2 = lam_um * lam_um
        n2 = mi.Float(1.0)
        for k, l in zip(mat.K, mat.L):
            n2 += float(k) * l2 / (l2 - float(l))
        return dr.sqrt(n2)
    raise InvalidValueError(f"material {mat.spec!r}: tabulated indices are not supported in the Mitsuba lens "
                     "camera; use a catalogue glass or 'n/V'")


def is_dispersive(lens: Lens) -> bool:
    """True when any surface's medium has a wavelength-dependent index."""
    return any(s.material.kind != "constant" for s in lens.surfaces)


FAST_SPHERE_MIN_SAG = 1e-2   # |c|·a above which a sphere is hit by the division-free root


def _surface_constants(lens: Lens) -> list[dict]:
    """Per-surface constants of the reverse trace as Python floats (they become kernel literals)."""
    zv = lens.vertex_z_mm
    media = lens.media()
    out = []
    for i in reversed(range(len(lens.surfaces))):
        s = lens.surfaces[i]
        c = float(s.curvature_per_mm)
        sphere = c != 0.0 and s.conic == 0.0 and not s.is_aspheric
        out.append({"surface": s, "z": float(zv[i]), "c": c, "kk": 1.0 + float(s.conic),
                    "r2": float(s.semi_aperture_mm) ** 2, "after": media[i + 1], "before": media[i],
                    "sphere": sphere,
                    "fast": sphere and abs(c) * float(s.semi_aperture_mm) > FAST_SPHERE_MIN_SAG})
    return out


def hit_sphere_fast(k, px, py, qz, dx, dy, dz, dr):
    """Hit of a unit-direction ray with a strongly curved sphere c|p|² − 2z = 0 (vertex-relative):
    t = (−b ± √(b² − cC))/c with PBRT's root rule (the root that meets the vertex cap of a ray
    travelling −z is (−b + √·)/c for either sign of c), no division. Its float32 error, about
    2⁻²⁴/|c|, stays below 6·10⁻⁶ of the clear aperture for |c|·a > FAST_SPHERE_MIN_SAG; flatter
    spheres take the stable two-root form. Returns (t, hit)."""
    c = k["c"]
    b = dr.fma(c, dr.fma(px, dx, dr.fma(py, dy, qz * dz)), -dz)
    C = dr.fma(c, dr.fma(px, px, dr.fma(py, py, qz * qz)), -2.0 * qz)
    disc = dr.fma(b, b, -c * C)
    sq = dr.sqrt(dr.maximum(disc, 0.0))
    t = (dr.select(dz < 0.0, sq, -sq) - b) * (1.0 / c)
    hit = (disc >= 0.0) & (t >= -1e-9) & (c * dr.fma(t, dz, qz) <= 1.0 + 1e-6)
    return t, hit


def hit_general(k, px, py, qz, dx, dy, dz, dr):
    """Hit of a flat, conic, aspheric or nearly flat surface by the stable vertex-relative roots
    C/q and q/A: the nearest ahead on the vertex branch (Newton refinement for aspheres).
    Returns (t, hit)."""
    c, kk, s = k["c"], k["kk"], k["surface"]
    dz_ok = dr.abs(dz) > 1e-12
    t_plane = -qz / dr.select(dz_ok, dz, 1.0)
    if c == 0.0 and not s.is_aspheric:
        return t_plane, dz_ok & (t_plane >= -1e-9)
    if c == 0.0:
        t, hit = t_plane, dz_ok
    else:
        A = c * (dx * dx + dy * dy + kk * dz * dz)
        b = c * (px * dx + py * dy + kk * qz * dz) - dz
        C = c * (px * px + py * py + kk * qz * qz) - 2.0 * qz
        disc = b * b - A * C
        q = -(b + dr.copysign(dr.sqrt(dr.maximum(disc, 0.0)), b))
        t1 = C / dr.select(q != 0.0, q, 1.0)
        t2 = q / dr.select(A != 0.0, A, 1.0)
        ok1 = (q != 0.0) & (t1 >= -1e-9) & (kk * c * (qz + t1 * dz) <= 1.0 + 1e-9)
        ok2 = (A != 0.0) & (t2 >= -1e-9) & (kk * c * (qz + t2 * dz) <= 1.0 + 1e-9)
        t = dr.select(ok1 & (~ok2 | (t1 <= t2)), t1, t2)
        hit = (disc >= 0.0) & (ok1 | ok2)
    if s.is_aspheric:
        t, hit = _newton_asphere(s, px, py, qz, dx, dy, dz, dr.select(hit, t, t_plane), dr)
    return t, hit


def trace_reverse(lens: Lens, px, py, pz, dx, dy, dz, wl, dr, mi):
    """Trace Dr.Jit rays (lens coordinates, unit directions travelling −z) from the sensor to object
    space at wavelength `wl` (a Dr.Jit Float, or None for the d-line indices as constants).
    Returns (px, py, pz, dx, dy, dz, valid).

    Per surface, only what it needs: strongly curved spheres the division-free hit
    (hit_sphere_fast), other surfaces the stable one; spheres skip normalising their normal
    (−cx, −cy, 1 − cz), unit length on the surface; flat surfaces refract with n = (0, 0, 1); the
    stop only clips. Arithmetic is fused (dr.fma) and constants are Python floats."""
    valid = mi.Bool(True)
    for k in _surface_constants(lens):
        s, c, kk = k["surface"], k["c"], k["kk"]
        qz = pz - k["z"]
        t, hit = (hit_sphere_fast if k["fast"] else hit_general)(k, px, py, qz, dx, dy, dz, dr)
        px, py, qz = dr.fma(t, dx, px), dr.fma(t, dy, py), dr.fma(t, dz, qz)
        pz = qz + k["z"]
        valid &= hit & (dr.fma(px, px, py * py) <= k["r2"])
        if wl is None:
            n1, n2 = float(k["after"].nd), float(k["before"].nd)
        else:
            n1, n2 = index_expr(k["after"], wl, dr, mi), index_expr(k["before"], wl, dr, mi)
        if s.is_stop or (isinstance(n1, float) and isinstance(n2, float) and n1 == n2):
            continue
        mu = n1 / n2
        mu2 = mu * mu
        if c == 0.0 and not s.is_aspheric:          # flat: normal (0, 0, 1)
            kt = dr.fma(mu2, dz * dz, 1.0 - mu2)
            valid &= kt >= 0.0
            coef = dr.fma(-mu, dz, dr.copysign(dr.sqrt(dr.maximum(kt, 0.0)), dz))
            dx, dy, dz = mu * dx, mu * dy, dr.fma(mu, dz, coef)
            continue
        if s.is_aspheric:
            _, ds = _sag_dr(s, px * px + py * py, dr)
            nx, ny, nz = -2.0 * px * ds, -2.0 * py * ds, mi.Float(1.0)
        else:
            nx, ny, nz = -c * px, -c * py, dr.fma(-c * kk, qz, 1.0)
        if not k["sphere"]:
            inv = dr.rsqrt(nx * nx + ny * ny + nz * nz)
            nx, ny, nz = nx * inv, ny * inv, nz * inv
        cosi = dr.fma(dx, nx, dr.fma(dy, ny, dz * nz))
        # d' = μd + (±√k − μ cosi) n with the root's sign that of cosi: unit length, either normal sense.
        kt = dr.fma(mu2, cosi * cosi, 1.0 - mu2)
        valid &= kt >= 0.0
        coef = dr.fma(-mu, cosi, dr.copysign(dr.sqrt(dr.maximum(kt, 0.0)), cosi))
        dx, dy, dz = dr.fma(mu, dx, coef * nx), dr.fma(mu, dy, coef * ny), dr.fma(mu, dz, coef * nz)
    return px, py, pz, dx, dy, dz, valid


def _sag_dr(s, rho, dr):
    """Sag and d(sag)/d(r²) of an even asphere as Dr.Jit expressions of rho = r²."""
    c, kk = float(s.curvature_per_mm), 1.0 + float(s.conic)
    root = dr.sqrt(dr.maximum(1.0 - kk * c * c * rho, 0.0))
    sag = c * rho / (1.0 + root)
    dsag = c / (2.0 * dr.maximum(root, 1e-12))
    power = 1.0
    for j, a in enumerate(s.asphere_coeffs):       # a · rho^(j+1); derivative (j+1) a rho^j
        dsag += (j + 1) * float(a) * power
        power = power * rho
        sag += float(a) * power
    return sag, dsag


def _newton_asphere(s, px, py, qz, dx, dy, dz, t, dr, iterations: int = 12):
    """Refine the conic hit t onto the even asphere by Newton's method; returns (t, hit)."""
    for _ in range(iterations):
        x, y, z = px + t * dx, py + t * dy, qz + t * dz
        sag, ds = _sag_dr(s, x * x + y * y, dr)
        fp = dz - 2.0 * ds * (x * dx + y * dy)
        t = t - (z - sag) / dr.select(fp != 0.0, fp, 1.0)
    x, y, z = px + t * dx, py + t * dy, qz + t * dz
    rho = x * x + y * y
    sag, _ = _sag_dr(s, rho, dr)
    c, kk = float(s.curvature_per_mm), 1.0 + float(s.conic)
    tol_mm = 1e-5 * max(1.0, float(s.semi_aperture_mm))   # float32 variants: ~1e-7 relative
    hit = (dr.abs(z - sag) < tol_mm) & (1.0 - kk * c * c * rho >= 0.0) & (t >= -1e-9)
    return t, hit
