"""Lens summaries and figures: the numbers behind `workbench lens info` and the PNGs of `lens plot`."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError
from workbench.optics.lens.analysis import (axial_color, distortion, lateral_color, ray_fan, real_fov_deg,
                                            relative_illumination, spot_diagram)
from workbench.optics.lens.glass import LINE_C_NM, LINE_D_NM, LINE_F_NM
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial, sensor_distance_mm, sensor_z_mm
from workbench.optics.lens.psf import diffraction_mtf, mtf_from_psf, psf_diffraction
from workbench.optics.lens.pupil import chief_ray_on_sensor, make_bundle

FIELD_FRACTIONS = (0.0, 0.5, 0.7, 1.0)


def max_field_deg(lens: Lens, step_deg: float = 1.0, limit_deg: float = 89.0) -> float:
    """Largest field angle (deg, on a step grid) whose chief ray reaches the sensor."""
    best = 0.0
    a = step_deg
    while a <= limit_deg:
        try:
            chief_ray_on_sensor(lens, a, LINE_D_NM)
        except ValueError:
            break
        best = a
        a += step_deg
    return best


def lens_summary(lens: Lens, max_field: float | None = None,
                 sensor_mm: tuple[float, float] | None = None) -> dict:
    """Paraxial data and an aberration summary at FIELD_FRACTIONS of `max_field` (deg; default the
    largest traceable field, or the sensor's half-diagonal field when `sensor_mm` = (width, height)
    is given, which also adds the paraxial and real (chief-ray) fields of view)."""
    p = paraxial(lens)
    fov = None
    if sensor_mm is not None:
        w, h = sensor_mm
        d = math.hypot(w, h)
        fov = {k: {"paraxial_deg": p.fov_deg(v), "real_deg": _real_fov_or_none(lens, v)}
               for k, v in (("horizontal", w), ("vertical", h), ("diagonal", d))}
        if max_field is None and fov["diagonal"]["real_deg"] is not None:
            max_field = fov["diagonal"]["real_deg"] / 2
    mf = max_field_deg(lens) if max_field is None else float(max_field)
    fields = [round(f * mf, 6) for f in FIELD_FRACTIONS]
    dist = distortion(lens, fields)
    lat, lat_ok = lateral_color(lens, fields)
    heights = [float(h) if ok else 0.0 for h, ok in zip(dist.real_height_mm, dist.valid)]
    ri = relative_illumination(lens, heights)
    rows = []
    for i, f in enumerate(fields):
        try:
            rms = spot_diagram(lens, f).rms_um
        except ValueError:
            rms = None
        rows.append({"field_deg": f, "image_height_mm": heights[i] if dist.valid[i] else None,
                     "spot_rms_um": rms,
                     "distortion_pct": float(dist.distortion_percent[i]) if dist.valid[i] else None,
                     "relative_illumination": float(ri[i]) if dist.valid[i] else None,
                     "lateral_color_um": float(lat[i]) if lat_ok[i] else None})
    return {"name": lens.name, "description": lens.description, "n_surfaces": len(lens.surfaces),
            "paraxial": p.as_dict(), "sensor_distance_mm": sensor_distance_mm(lens),
            "field_of_view": fov, "max_field_deg": mf, "axial_color_mm": axial_color(lens), "fields": rows}


def _real_fov_or_none(lens: Lens, size_mm: float) -> float | None:
    try:
        return real_fov_deg(lens, size_mm)
    except ValueError:
        return None


def format_summary(s: dict) -> str:
    p = s["paraxial"]
    lines = [f"lens {s['name']}: {s['description']}".rstrip(": "),
             f"  EFL {p['efl_mm']:.4f} mm   BFL {p['bfl_mm']:.4f} mm   f/{p['f_number']:.3f}   "
             f"EPD {p['epd_mm']:.4f} mm   track {p['total_track_mm']:.4f} mm",
             f"  entrance pupil {p['entrance_pupil_mm']:.4f} mm behind the first vertex; exit pupil "
             f"{p['exit_pupil_mm']:.4f} mm from the last vertex (diameter {p['exit_pupil_diameter_mm']:.4f})",
             f"  sensor {s['sensor_distance_mm']:.4f} mm behind the last vertex; "
             f"axial colour BFL(F)−BFL(C) {s['axial_color_mm'] * 1e3:.2f} µm",
             f"  field (max {s['max_field_deg']:g}°):",
             "    field°   height mm   spot RMS µm   distortion %   rel. illum.   lateral colour µm"]

    def f(v, fmt):
        return format(v, fmt) if v is not None else "—"
    if s.get("field_of_view"):
        lines.insert(-2, "  field of view (paraxial / real chief ray): " + ", ".join(
            f"{k} {f(v['paraxial_deg'], '.2f')}° / {f(v['real_deg'], '.2f')}°"
            for k, v in s["field_of_view"].items()))
    for r in s["fields"]:
        lines.append(f"    {r['field_deg']:6.2f}   {f(r['image_height_mm'], '9.4f')}   "
                     f"{f(r['spot_rms_um'], '11.3f')}   {f(r['distortion_pct'], '12.3f')}   "
                     f"{f(r['relative_illumination'], '11.3f')}   {f(r['lateral_color_um'], '8.3f')}")
    return "\n".join(lines)


# ------------------------------------------------------------------ figures
# Each draw_* function draws one chart of a lens on a matplotlib Figure (no pyplot, so the GUI can
# build figures on a worker thread and the command line can save them); write_plots saves them all.
WAVELENGTH_LINES = ((LINE_F_NM, "tab:blue"), (LINE_D_NM, "tab:green"), (LINE_C_NM, "tab:red"))
PSF_WAVELENGTH_NM = 550.0


def plot_layout(lens: Lens, ax, fields_deg) -> None:
    """Cross-section (y–z) with a meridional fan per field traced to the sensor."""
    zv = lens.vertex_z_mm
    for i, s in enumerate(lens.surfaces):
        y = np.linspace(-s.semi_aperture_mm, s.semi_aperture_mm, 61)
        if s.is_stop:
            top = s.semi_aperture_mm * 1.3
            ax.plot([zv[i]] * 2, [s.semi_aperture_mm, top], "k", lw=2)
            ax.plot([zv[i]] * 2, [-s.semi_aperture_mm, -top], "k", lw=2)
            continue
        ax.plot(zv[i] + s.sag_mm(y), y, "k", lw=1)
        if not s.material.is_air and i + 1 < len(lens.surfaces):
            # Element edge: each face runs out flat to the larger clear radius, then a rim joins them.
            n = lens.surfaces[i + 1]
            ya = max(s.semi_aperture_mm, n.semi_aperture_mm)
            za = zv[i] + float(s.sag_mm(s.semi_aperture_mm))
            zb = zv[i + 1] + float(n.sag_mm(n.semi_aperture_mm))
            for sgn in (1, -1):
                ax.plot([za, za, zb, zb], [sgn * s.semi_aperture_mm, sgn * ya, sgn * ya,
                                           sgn * n.semi_aperture_mm], "k", lw=1)
    zs = sensor_z_mm(lens)
    colours = ["tab:blue", "tab:green", "tab:red", "tab:purple"]
    for k, f in enumerate(fields_deg):
        try:
            b = make_bundle(lens, f, math.inf, LINE_D_NM)
        except ValueError:
            continue
        _, _, v0, v1 = b.box
        v = np.linspace(v0, v1, 11)
        r = b.trace(np.zeros_like(v), v, LINE_D_NM, record=True)
        path = r.path_mm
        end = r.points + r.dirs * ((zs - r.points[:, 2]) / np.where(r.dirs[:, 2] != 0, r.dirs[:, 2], 1))[:, None]
        for j in np.nonzero(r.valid)[0]:
            start = path[0, j] + b.d0 * (path[1, j, 2] - path[0, j, 2] - 0.15 * lens.total_track_mm) / b.d0[2]
            pts = np.vstack([start, path[1:, j], end[j]])
            ax.plot(pts[:, 2], pts[:, 1], color=colours[k % 4], lw=0.6)
    ax.axvline(zs, color="0.5", lw=1)
    ax.set_aspect("equal")
    ax.set_xlabel("z (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"{lens.name}: layout and ray fans")


def field_angles(lens: Lens, max_field: float | None = None) -> list[float]:
    """The fields the charts use: FIELD_FRACTIONS of max_field (default the largest traceable)."""
    mf = max_field_deg(lens) if max_field is None else float(max_field)
    return [f * mf for f in FIELD_FRACTIONS]


def draw_layout(fig, lens: Lens, fields: list[float]) -> None:
    plot_layout(lens, fig.add_subplot(), fields[::-1][:3])


def draw_spots(fig, lens: Lens, fields: list[float]) -> None:
    """Spot diagrams at each field for the F, d and C lines."""
    axes = fig.subplots(1, len(fields), squeeze=False)[0]
    for ax, f in zip(axes, fields):
        for wl, col in WAVELENGTH_LINES:
            try:
                sd = spot_diagram(lens, f, wl, n_side=24)
            except ValueError:
                continue
            ax.plot(sd.x_um, sd.y_um, ".", ms=1.5, color=col)
            if wl == LINE_D_NM:
                ax.set_title(f"{f:.1f}°  RMS {sd.rms_um:.2f} µm", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x (µm)")
    axes[0].set_ylabel("y (µm)")


def draw_ray_fans(fig, lens: Lens, fields: list[float]) -> None:
    """Tangential and sagittal ray-fan errors at each field for the F, d and C lines."""
    axes = fig.subplots(2, len(fields), sharex=True, squeeze=False)
    for k, f in enumerate(fields):
        for wl, col in WAVELENGTH_LINES:
            try:
                fan = ray_fan(lens, f, wl)
            except ValueError:
                continue
            axes[0, k].plot(fan.pupil_t[fan.valid_t], fan.error_t_um[fan.valid_t], color=col)
            axes[1, k].plot(fan.pupil_s[fan.valid_s], fan.error_s_um[fan.valid_s], color=col)
        axes[0, k].set_title(f"{f:.1f}° tangential", fontsize=9)
        axes[1, k].set_title("sagittal", fontsize=9)
        axes[1, k].set_xlabel("pupil (mm)")
    axes[0, 0].set_ylabel("εy (µm)")
    axes[1, 0].set_ylabel("εx (µm)")


def field_psf(lens: Lens, field_deg: float, wavelength_nm: float = PSF_WAVELENGTH_NM):
    """(PSF, grid spacing µm) at a field angle for an object at infinity, or None if untraceable."""
    lam = wavelength_nm
    try:
        h = chief_ray_on_sensor(lens, field_deg, lam)[1]
        rms = spot_diagram(lens, field_deg, lam, n_side=24).rms_um
    except ValueError:
        return None
    spacing = max(lam * 1e-3 * paraxial(lens).f_number / 4, 10 * rms / 256)
    size = int(np.clip(2 ** math.ceil(math.log2(max(10 * rms / spacing, 64))), 64, 256))
    try:
        return psf_diffraction(lens, h, lam, math.inf, spacing, size), spacing
    except ValueError:
        return None


def draw_psf(fig, lens: Lens, fields: list[float]) -> None:
    """Diffraction PSF (550 nm, log scale) at each field."""
    axes = fig.subplots(1, len(fields), squeeze=False)[0]
    for ax, f in zip(axes, fields):
        got = field_psf(lens, f)
        ax.set_title(f"{f:.1f}°", fontsize=9)
        if got is None:
            ax.text(0.5, 0.5, "not traceable", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
            continue
        psf, spacing = got
        half = psf.shape[0] * spacing / 2
        ax.imshow(np.log10(psf / psf.max() + 1e-4), extent=(-half, half, -half, half), cmap="magma",
                  origin="lower")
        ax.set_xlabel("x (µm)")
    axes[0].set_ylabel("y (µm)")
    fig.suptitle(f"PSF at {PSF_WAVELENGTH_NM:g} nm (log10, 4 decades)", fontsize=9)


def draw_mtf(fig, lens: Lens, fields: list[float]) -> None:
    """Tangential and sagittal MTF from the diffraction PSF at each field, with the diffraction limit."""
    ax = fig.add_subplot()
    lam = PSF_WAVELENGTH_NM
    p = paraxial(lens)
    nu_c = 1.0 / (lam * 1e-6 * p.f_number)
    for f, col in zip(fields, ("k", "tab:blue", "tab:green", "tab:red")):
        got = field_psf(lens, f, lam)
        if got is None:
            continue
        psf, spacing = got
        for axis, ls in (("y", "-"), ("x", "--")):
            fr, m = mtf_from_psf(psf, spacing, axis)
            keep = fr <= nu_c
            ax.plot(fr[keep], m[keep], ls, color=col, label=f"{f:.1f}° {'T' if axis == 'y' else 'S'}")
    fr = np.linspace(0, nu_c, 200)
    ax.plot(fr, diffraction_mtf(fr, lam, p.f_number), ":", color="0.4", label="diffraction limit")
    ax.set_xlabel("cycles/mm")
    ax.set_ylabel(f"MTF ({lam:g} nm)")
    ax.legend(fontsize=7)


def _distortion_curve(lens: Lens, fields: list[float]):
    angles = np.linspace(0, max(fields), 25)
    return angles, distortion(lens, angles)


def draw_distortion(fig, lens: Lens, fields: list[float]) -> None:
    """Distortion (%) against field angle up to the largest field."""
    angles, d = _distortion_curve(lens, fields)
    ax = fig.add_subplot()
    ax.plot(d.distortion_percent[d.valid], angles[d.valid])
    ax.set_xlabel("distortion (%)")
    ax.set_ylabel("field (deg)")


def draw_relative_illumination(fig, lens: Lens, fields: list[float]) -> None:
    """Traced relative illumination against image height, with cos⁴θ for comparison."""
    angles, d = _distortion_curve(lens, fields)
    h = d.real_height_mm[d.valid]
    ri = relative_illumination(lens, h, n_side=64)
    ax = fig.add_subplot()
    ax.plot(h, ri, label="traced")
    ax.plot(h, np.cos(np.radians(angles[d.valid])) ** 4, "--", label="cos⁴θ")
    ax.set_xlabel("image height (mm)")
    ax.set_ylabel("relative illumination")
    ax.legend()


CHARTS = {"layout": (draw_layout, (9, 5)), "spots": (draw_spots, (12.8, 3.4)),
          "ray_fans": (draw_ray_fans, (12.8, 5)), "psf": (draw_psf, (12.8, 3.4)),
          "mtf": (draw_mtf, (6, 4)), "distortion": (draw_distortion, (5, 4)),
          "relative_illumination": (draw_relative_illumination, (5, 4))}
"""Chart name → (draw function, figure size in inches)."""
LENS_ERRORS = (WorkbenchError, ValueError, TypeError, KeyError, ZeroDivisionError)
"""What tracing or analysing a malformed or untraceable lens raises."""


def draw_chart(fig, name: str, lens: Lens, field_limit_deg: float) -> None:
    """Chart `name` of CHARTS for `lens` at field angles up to field_limit_deg (or as far as the
    lens traces) on `fig`; a lens that cannot be traced draws why."""
    draw, _size = CHARTS[name]
    try:
        draw(fig, lens, field_angles(lens, min(field_limit_deg, max_field_deg(lens))))
    except LENS_ERRORS as exc:
        fig.clear()
        fig.text(0.5, 0.5, f"{name}: {exc}", ha="center", va="center", wrap=True)


def draw_no_lens(fig) -> None:
    fig.text(0.5, 0.5, "no lens: first-order optics", ha="center")


def write_plots(lens: Lens, out_dir, max_field: float | None = None) -> list[Path]:
    """One PNG per chart of CHARTS (layout.png, spots.png, …, relative_illumination.png), written
    together (files.atomic_write_files: all or none, so a full disk leaves no empty PNG and names
    the file)."""
    import io

    from matplotlib.figure import Figure

    from workbench.files import atomic_write_files
    out = Path(out_dir)
    fields = field_angles(lens, max_field)
    pngs = {}
    for name, (draw, size) in CHARTS.items():
        fig = Figure(figsize=size, layout="tight")
        draw(fig, lens, fields)
        buf = io.BytesIO()
        fig.savefig(buf, dpi=110, format="png")
        pngs[out / f"{name}.png"] = buf.getvalue()
    atomic_write_files(pngs)
    return list(pngs)
