"""Charts of camera metrics on any matplotlib Figure (the command line's PNGs and the window's
Metrics dock): MTF curves with the Nyquist marker, SNR against signal with the model, ΔE2000 per
Macbeth patch; one design, or several side by side (A/B comparison)."""
from __future__ import annotations

import numpy as np

from workbench.metrics.colour import PATCH_NAMES

DESIGN_STYLES = ("-", "--", ":", "-.")
PLANE_COLOURS = {"optics alone": "0.6", "linear": "tab:cyan", "sRGB": "tab:purple"}


RAW_COLOURS = {"R": "tab:red", "G": "tab:green", "B": "tab:blue"}


def _plane_colour(name: str) -> str:
    if name.startswith("raw "):                      # each raw channel in its own colour
        return RAW_COLOURS.get(name[4:], "tab:olive")
    return next((c for key, c in PLANE_COLOURS.items() if name.startswith(key)), "k")


def draw_mtf(ax, designs: list[dict]) -> None:
    """MTF against frequency (cycles/pixel) of every plane of each design; Nyquist dashed."""
    for d, metrics in enumerate(designs):
        for row in metrics["mtf"]:
            label = row["plane"] + (f" ({metrics['project']})" if len(designs) > 1 else "")
            ax.plot(row["frequency_cy_px"], row["mtf"], DESIGN_STYLES[d % 4], color=_plane_colour(row["plane"]),
                    lw=1.2, label=label)
    ax.axvline(0.5, color="k", ls="--", lw=0.8)
    ax.text(0.5, 1.02, " Nyquist", fontsize=7, va="bottom")
    ax.set(xlim=(0, 1.0), ylim=(0, 1.1), xlabel="frequency (cycles/pixel)", ylabel="MTF",
           title="system MTF (ISO 12233 slanted edge)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6)


def _values(rows: list[dict], key: str) -> np.ndarray:
    """rows' key as floats, None (a value with no finite figure: metrics.bounds) as NaN, not drawn."""
    return np.array([np.nan if r.get(key) is None else r[key] for r in rows], np.float64)


def draw_snr(ax, designs: list[dict]) -> None:
    """SNR against mean signal (e⁻) per channel, measured (points) and the noise model (line)."""
    for d, metrics in enumerate(designs):
        by_channel: dict[str, list] = {}
        for row in metrics["noise"]:
            by_channel.setdefault(row["channel"], []).append(row)
        for ch, rows in by_channel.items():
            rows = sorted(rows, key=lambda r: r["mean_e"])
            e = np.array([r["mean_e"] for r in rows])
            colour = {"R": "tab:red", "G": "tab:green", "B": "tab:blue"}.get(ch, "k")
            tag = f" ({metrics['project']})" if len(designs) > 1 else ""
            ax.loglog(e, _values(rows, "snr"), "o", ms=3, color=colour, alpha=0.8 if d == 0 else 0.5,
                      label=f"{ch} measured{tag}")
            ax.loglog(e, _values(rows, "snr_model"), DESIGN_STYLES[d % 4], color=colour, lw=0.8)
        neutral = metrics.get("colour", {}).get("neutral_noise", [])
        if neutral:
            ax.loglog(_values(neutral, "mean_e"), _values(neutral, "snr"), "x", ms=4, color="0.3",
                      alpha=0.8 if d == 0 else 0.5, label="Macbeth neutrals" + (f" ({metrics['project']})"
                                                                               if len(designs) > 1 else ""))
    ax.set(xlabel="mean signal (e⁻)", ylabel="SNR", title="SNR against signal (•: uniform field, ×: neutrals, lines: model)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=6)


def draw_delta_e(ax, designs: list[dict]) -> None:
    """ΔE2000 per Macbeth patch, one bar per design."""
    width = 0.8 / len(designs)
    x = np.arange(24)
    for d, metrics in enumerate(designs):
        ax.bar(x + (d - (len(designs) - 1) / 2) * width, metrics["colour"]["patches"], width,
               label=f"{metrics['project']}: mean {metrics['colour']['mean']:.1f}")
    ax.set_xticks(x, PATCH_NAMES, rotation=60, ha="right", fontsize=6)
    ax.set(ylabel="ΔE2000", title="colour error per Macbeth patch (exposure-matched on neutral 5)")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")


def draw_metrics(fig, designs: list[dict]) -> None:
    """MTF, SNR and ΔE of one or several designs on `fig` (three panels)."""
    axes = fig.subplot_mosaic([["mtf", "snr"], ["de", "de"]])
    draw_mtf(axes["mtf"], designs)
    draw_snr(axes["snr"], designs)
    draw_delta_e(axes["de"], designs)


def draw_pareto(ax, rows: list[dict], x: str, y: str, higher_x: bool = True, higher_y: bool = True,
                fields: list[str] | None = None) -> None:
    """Designs as points of two metrics, the Pareto-optimal ones joined and every one labelled
    (by its values of `fields`, named in the title, when given; else by its name)."""
    def label(r: dict) -> str:
        return ", ".join(f"{r[f]:g}" if isinstance(r[f], (int, float)) else str(r[f]) for f in fields) \
            if fields else r["design"]
    names = {r["design"]: label(r) for r in rows}
    pts = [(r[x], r[y], r["design"]) for r in rows if r.get(x) is not None and r.get(y) is not None]
    if not pts:
        ax.text(0.5, 0.5, "no designs measured yet", ha="center", va="center", transform=ax.transAxes)
        return
    best = set(pareto_front(rows, x, y, higher_x, higher_y))
    front = sorted(p for p in pts if p[2] in best)
    ax.plot([p[0] for p in pts], [p[1] for p in pts], "o", color="0.6")
    ax.plot([p[0] for p in front], [p[1] for p in front], "o-", color="tab:red", label="Pareto front")
    for px, py, name in pts:
        ax.annotate(names[name], (px, py), fontsize=7, xytext=(4, 3), textcoords="offset points")
    title = "design study" + (f" (points: {', '.join(f.rsplit('.', 1)[-1] for f in fields)})" if fields else "")
    arrows = f"{'→' if higher_x else '←'} better, {'↑' if higher_y else '↓'} better"
    ax.set(xlabel=x, ylabel=y, title=f"{title}\n{arrows}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def pareto_front(rows: list[dict], x: str, y: str, higher_x: bool = True, higher_y: bool = True) -> list[str]:
    """Names of the designs no other design beats in both metrics."""
    sx, sy = (1 if higher_x else -1), (1 if higher_y else -1)
    pts = [(r[x], r[y], r["design"]) for r in rows if r.get(x) is not None and r.get(y) is not None]
    return [p[2] for p in pts if not any(sx * q[0] >= sx * p[0] and sy * q[1] >= sy * p[1] and q[:2] != p[:2]
                                         for q in pts)]


def chart_rgba(draw, width_px: int, height_px: int, dpi: float = 100.0) -> np.ndarray:
    """draw(fig) on a fresh Agg figure of width_px×height_px → H×W×4 uint8 (no pyplot, no Qt: safe
    on a worker thread or in a worker process)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi, layout="constrained")
    draw(fig)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba()).copy()


def characterise_and_draw(params, seed: int, size_px: int, chart_px: tuple[int, int]):
    """sensor.emva.characterize(params), then its photon-transfer chart rasterised at chart_px
    (w, h): (result, H×W×4 uint8). The window's Sensor editor runs this in its side process."""
    from workbench.sensor.emva import characterize, draw_photon_transfer
    result = characterize(params, seed=seed, size_px=size_px)
    return result, chart_rgba(lambda fig: draw_photon_transfer(result, fig), *chart_px)


def measure_and_draw(project, pinned: dict | None, chart_px: tuple[int, int]):
    """camera_metrics of the project and the chart of it beside the pinned design's (the window's
    Metrics panel runs this in a worker process). Returns (metrics, chart RGBA, seconds)."""
    import time

    from workbench.metrics.frame import camera_metrics
    t0 = time.perf_counter()
    metrics = camera_metrics(project)
    designs = [pinned, metrics] if pinned is not None else [metrics]
    if pinned is not None and pinned["project"] == metrics["project"]:
        designs = [{**pinned, "project": f"A: {pinned['project']}"}, {**metrics, "project": f"B: {metrics['project']}"}]
    rgba = chart_rgba(lambda fig: draw_metrics(fig, designs), *chart_px)
    return metrics, rgba, time.perf_counter() - t0

