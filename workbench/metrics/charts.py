"""Charts of camera metrics on any matplotlib Figure (the command line's PNGs and the window's
Metrics dock): MTF curves with the Nyquist marker, SNR against signal with the model, ΔE2000 per
Macbeth patch; one design, or several side by side (A/B comparison)."""
from __future__ import annotations

import numpy as np

from workbench.metrics.colour import PATCH_NAMES

DESIGN_STYLES = ("-", "--", ":", "-.")
PLANE_COLOURS = {"optics": "0.6", "pixel": "0.8", "linear": "tab:cyan", "sRGB": "tab:purple"}


RAW_COLOURS = {"R": "tab:red", "G": "tab:green", "B": "tab:blue"}


def _plane_colour(name: str) -> str:
    if name.startswith("raw "):                      # each raw channel in its own colour
        return RAW_COLOURS.get(name[4:], "tab:olive")
    return next((c for key, c in PLANE_COLOURS.items() if name.startswith(key)), "k")


def draw_mtf(ax, designs: list[dict]) -> None:
    """MTF against frequency (cycles/pixel) of every plane of each design, MTF50 ± 1σ in the legend,
    a raw plane's closed form (optics × pixel) thin beside it; Nyquist dashed."""
    for d, metrics in enumerate(designs):
        for row in metrics["mtf"]:
            m50, sd = row.get("mtf50_cy_px"), row.get("mtf50_sd_cy_px")
            label = (row["plane"] + ("" if m50 is None else f": MTF50 {m50:.3f}")
                     + ("" if m50 is None or sd is None else f" ± {sd:.3f}")
                     + (f" ({metrics['project']})" if len(designs) > 1 else ""))
            colour = _plane_colour(row["plane"])
            ax.plot(row["frequency_cy_px"], row["mtf"], DESIGN_STYLES[d % 4], color=colour, lw=1.2, label=label)
            if row.get("model_mtf") is not None:
                ax.plot(row["frequency_cy_px"], row["model_mtf"], DESIGN_STYLES[d % 4], color=colour, lw=0.5)
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
    """ΔE2000 per Macbeth patch, one bar per design: held out (leave-one-out fits), with the fitted
    (training) patches' as a mark on each bar; the sRGB output's when no colour matrix is fitted."""
    width = 0.8 / len(designs)
    x = np.arange(24)
    for d, metrics in enumerate(designs):
        colour, at = metrics["colour"], x + (d - (len(designs) - 1) / 2) * width
        held, fitted = colour.get("held_out"), colour.get("fitted")
        if held is None:
            out = colour["srgb_output"]
            ax.bar(at, out["patches"], width, label=f"{metrics['project']}: sRGB output, mean {out['mean']:.1f}")
            continue
        ax.bar(at, held["patches"], width, label=f"{metrics['project']}: held out, mean {held['mean']:.2f}")
        ax.plot(at, fitted["patches"], "_", color="k", ms=6,
                label=f"{metrics['project']}: fitted (training) patches, mean {fitted['mean']:.2f}")
    ax.set_xticks(x, PATCH_NAMES, rotation=60, ha="right", fontsize=6)
    ax.set(ylabel="ΔE2000", title="colour error per Macbeth patch (flat-fielded, exposure-matched on neutral 5; "
                                   "bars: held out, —: fitted)")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")


def draw_metrics(fig, designs: list[dict]) -> None:
    """MTF, SNR and ΔE of one or several designs on `fig` (three panels)."""
    axes = fig.subplot_mosaic([["mtf", "snr"], ["de", "de"]])
    draw_mtf(axes["mtf"], designs)
    draw_snr(axes["snr"], designs)
    draw_delta_e(axes["de"], designs)


def draw_pareto(ax, rows: list[dict], x: str, y: str, higher_x: bool = True, higher_y: bool = True,
                fields: list[str] | None = None, sigma: dict[str, tuple] | None = None) -> None:
    """Designs as points of two metrics with ±2σ bars (sigma: pareto_front's), the ones on the
    ε-Pareto front joined and every one labelled (by its values of `fields`, named in the title,
    when given; else by its name)."""
    def label(r: dict) -> str:
        return ", ".join(f"{r[f]:g}" if isinstance(r[f], (int, float)) else str(r[f]) for f in fields) \
            if fields else r["design"]
    names = {r["design"]: label(r) for r in rows}
    pts = [(r[x], r[y], r["design"]) for r in rows if r.get(x) is not None and r.get(y) is not None]
    if not pts:
        ax.text(0.5, 0.5, "no designs measured yet", ha="center", va="center", transform=ax.transAxes)
        return
    best = set(pareto_front(rows, x, y, higher_x, higher_y, sigma))
    front = sorted(p for p in pts if p[2] in best)
    bars = [tuple(2 * (s or 0.0) for s in (sigma or {}).get(p[2], (None, None))) for p in pts]
    ax.errorbar([p[0] for p in pts], [p[1] for p in pts], xerr=[b[0] for b in bars], yerr=[b[1] for b in bars],
                fmt="o", color="0.6", elinewidth=0.8, capsize=2)
    ax.plot([p[0] for p in front], [p[1] for p in front], "o-", color="tab:red", label="Pareto front (ε-dominance)")
    for px, py, name in pts:
        ax.annotate(names[name], (px, py), fontsize=7, xytext=(4, 3), textcoords="offset points")
    title = "design study" + (f" (points: {', '.join(f.rsplit('.', 1)[-1] for f in fields)})" if fields else "")
    arrows = f"{'→' if higher_x else '←'} better, {'↑' if higher_y else '↓'} better"
    ax.set(xlabel=x, ylabel=y, title=f"{title}\n{arrows}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def pareto_front(rows: list[dict], x: str, y: str, higher_x: bool = True, higher_y: bool = True,
                 sigma: dict[str, tuple] | None = None) -> list[str]:
    """Names of the designs no other design ε-dominates in the two metrics (study.epsilon_dominates:
    better by more than ε on one, worse by no more than ε on the other; ε from the designs'
    uncertainties, sigma: design name → (σ_x, σ_y); none given: 0, the plain Pareto front)."""
    from workbench.metrics.tolerance import epsilon_dominates
    sigma = sigma or {}
    pts = {r["design"]: tuple(zip((r[x], r[y]), sigma.get(r["design"], (None, None))))
           for r in rows if r.get(x) is not None and r.get(y) is not None}
    return [name for name, p in pts.items()
            if not any(epsilon_dominates(q, p, (higher_x, higher_y)) for other, q in pts.items() if other != name)]


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

