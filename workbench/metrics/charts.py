"""Charts of camera metrics on any matplotlib Figure (the command line's PNGs and the window's
Metrics dock): MTF curves with the Nyquist marker, SNR against signal with the model, ΔE2000 per
Macbeth patch; one design, or several side by side (A/B comparison)."""
from __future__ import annotations

import numpy as np

from workbench.metrics.colour import PATCH_NAMES

DESIGN_STYLES = ("-", "--", ":", "-.")
DESIGN_MARKERS = ("o", "^", "s", "D")
PLANE_COLOURS = {"optics": "0.6", "pixel": "0.8", "linear": "tab:cyan", "sRGB": "tab:purple"}
RAW_COLOURS = {"R": "tab:red", "G": "tab:green", "B": "tab:blue"}
CHART_TITLES = {"mtf": "system MTF (ISO 12233 slanted edge)", "snr": "SNR against signal",
                "de": "ΔE2000 per Macbeth patch"}
LEGEND_TITLES = {"mtf": "MTF50 (cy/px) of each plane"}
LEGEND_FONT_PT = 7
HANDLE_WIDTH_IN = 0.45               # a legend column's handle, its padding and the space between columns


def _plane_colour(name: str) -> str:
    if name.startswith("raw "):                      # each raw channel in its own colour
        return RAW_COLOURS.get(name[4:], "tab:olive")
    return next((c for key, c in PLANE_COLOURS.items() if name.startswith(key)), "k")


def design_label(metrics: dict) -> str:
    """A design's name on the charts: its 'label' (A/B: what differs, project.difference_labels),
    else its project's name."""
    return metrics.get("label") or metrics["project"]


def _design_handles(designs: list[dict], markers: bool = False) -> list:
    """Legend entries telling several designs apart by line style (and marker); none for one."""
    from matplotlib.lines import Line2D
    if len(designs) < 2:
        return []
    return [Line2D([], [], color="k", ls=DESIGN_STYLES[d % 4], marker=DESIGN_MARKERS[d % 4] if markers else None,
                   ms=4, lw=1.0, label=design_label(m)) for d, m in enumerate(designs)]


def draw_mtf(ax, designs: list[dict]) -> list:
    """MTF against frequency (cycles/pixel) of every plane of each design (colour: plane, line
    style: design), a raw plane's closed form (optics × pixel) thin beside it; Nyquist dashed.
    Returns the legend entries (LEGEND_TITLES): each plane with its MTF50 per design (± 1σ for one),
    the designs."""
    from matplotlib.lines import Line2D
    mtf50: dict[str, list[str]] = {}
    for d, metrics in enumerate(designs):
        for row in metrics["mtf"]:
            m50, sd = row.get("mtf50_cy_px"), row.get("mtf50_sd_cy_px")
            mtf50.setdefault(row["plane"], []).append(
                "—" if m50 is None else f"{m50:.3f}" + ("" if sd is None or len(designs) > 1 else f" ± {sd:.3f}"))
            colour = _plane_colour(row["plane"])
            ax.plot(row["frequency_cy_px"], row["mtf"], DESIGN_STYLES[d % 4], color=colour, lw=1.2)
            if row.get("model_mtf") is not None:
                ax.plot(row["frequency_cy_px"], row["model_mtf"], DESIGN_STYLES[d % 4], color=colour, lw=0.5)
    ax.axvline(0.5, color="k", ls="--", lw=0.8)
    ax.text(0.5, 1.02, " Nyquist", fontsize=7, va="bottom")
    ax.set(xlim=(0, 1.0), ylim=(0, 1.1), xlabel="frequency (cycles/pixel)", ylabel="MTF", title=CHART_TITLES["mtf"])
    ax.grid(alpha=0.3)
    handles = [Line2D([], [], color=_plane_colour(p), lw=1.2,
                      label=p if set(v) == {"—"} else f"{p}: {' → '.join(v)}") for p, v in mtf50.items()]
    handles.append(Line2D([], [], color="0.3", lw=0.5, label="thin: closed form (optics × pixel)"))
    return handles + _design_handles(designs)


def _values(rows: list[dict], key: str) -> np.ndarray:
    """rows' key as floats, None (a value with no finite figure: metrics.bounds) as NaN, not drawn."""
    return np.array([np.nan if r.get(key) is None else r[key] for r in rows], np.float64)


def draw_snr(ax, designs: list[dict]) -> list:
    """SNR against mean signal (e⁻) per channel, measured on the uniform field (filled marks), on
    the Macbeth neutrals (grey, hollow) and the noise model (lines); a design's marks and lines
    in its own marker and line style. Returns the legend entries."""
    from matplotlib.lines import Line2D
    channels: dict[str, str] = {}
    for d, metrics in enumerate(designs):
        marker, style = DESIGN_MARKERS[d % 4], DESIGN_STYLES[d % 4]
        by_channel: dict[str, list] = {}
        for row in metrics["noise"]:
            by_channel.setdefault(row["channel"], []).append(row)
        for ch, rows in by_channel.items():
            rows = sorted(rows, key=lambda r: r["mean_e"])
            e = np.array([r["mean_e"] for r in rows])
            channels[ch] = RAW_COLOURS.get(ch, "k")
            ax.loglog(e, _values(rows, "snr"), marker, ls="", ms=3, color=channels[ch], alpha=0.8)
            ax.loglog(e, _values(rows, "snr_model"), style, color=channels[ch], lw=0.8)
        neutral = metrics.get("colour", {}).get("neutral_noise", [])
        if neutral:
            ax.loglog(_values(neutral, "mean_e"), _values(neutral, "snr"), marker, ls="", ms=4, mfc="none",
                      color="0.3")
    ax.set(xlabel="mean signal (e⁻)", ylabel="SNR", title=CHART_TITLES["snr"])
    ax.grid(alpha=0.3, which="both")
    handles = [Line2D([], [], color=c, marker="o", ls="", ms=4, label=f"{ch}, uniform field")
               for ch, c in channels.items()]
    handles += [Line2D([], [], color="0.3", marker="o", mfc="none", ls="", ms=4, label="Macbeth neutrals"),
                Line2D([], [], color="k", lw=0.8, label="lines: noise model")]
    return handles + _design_handles(designs, markers=True)


def draw_delta_e(ax, designs: list[dict]) -> list:
    """ΔE2000 per Macbeth patch, one bar per design: held out (leave-one-out fits), with the fitted
    (training) patches' as a mark on each bar; the sRGB output's when no colour matrix is fitted.
    Returns the legend entries."""
    width = 0.8 / len(designs)
    x = np.arange(24)
    handles = []
    for d, metrics in enumerate(designs):
        colour, at = metrics["colour"], x + (d - (len(designs) - 1) / 2) * width
        held, fitted = colour.get("held_out"), colour.get("fitted")
        name = f"{design_label(metrics)}: " if len(designs) > 1 else ""
        if held is None:
            out = colour["srgb_output"]
            handles.append(ax.bar(at, out["patches"], width, label=f"{name}sRGB output, mean {out['mean']:.1f}"))
            continue
        handles.append(ax.bar(at, held["patches"], width, label=f"{name}held out, mean {held['mean']:.2f}"))
        handles += ax.plot(at, fitted["patches"], "_", color="k", ms=6,
                           label=f"{name}fitted (training) patches, mean {fitted['mean']:.2f}")
    ax.set_xticks(x, PATCH_NAMES, rotation=60, ha="right", fontsize=6)
    ax.set(ylabel="ΔE2000", xlabel="patch (flat-fielded, exposure-matched on neutral 5)", title=CHART_TITLES["de"])
    ax.grid(alpha=0.3, axis="y")
    return handles


CHARTS = {"mtf": draw_mtf, "snr": draw_snr, "de": draw_delta_e}


def draw_chart(fig, designs: list[dict], chart: str) -> None:
    """One of CHARTS ('mtf', 'snr', 'de') of one or several designs filling `fig` (a constrained
    layout), its legend below the axes, outside the data, in as many columns as fit."""
    ax = fig.subplots()
    handles = CHARTS[chart](ax, designs)
    fig.legend(handles=handles, loc="outside lower center", fontsize=LEGEND_FONT_PT, title=LEGEND_TITLES.get(chart),
               title_fontsize=LEGEND_FONT_PT,
               ncols=legend_columns([h.get_label() for h in handles], fig.get_size_inches()[0] - 0.1))


def legend_columns(labels: list[str], width_in: float, most: int = 3) -> int:
    """The most columns (up to `most`, at least 1) a legend of `labels` may have within width_in:
    matplotlib fills them column by column, each as wide as its longest label plus the handle."""
    import math

    from matplotlib.textpath import TextPath
    widths = [TextPath((0, 0), label, size=LEGEND_FONT_PT).get_extents().width / 72 + HANDLE_WIDTH_IN
              for label in labels]
    for n in range(most, 1, -1):
        rows = math.ceil(len(widths) / n)
        if sum(max(widths[i:i + rows]) for i in range(0, len(widths), rows)) <= width_in:
            return n
    return 1


def draw_metrics(fig, designs: list[dict]) -> None:
    """MTF, SNR and ΔE of one or several designs on `fig` (three panels, each legend to the right
    of its axes, outside the data)."""
    axes = fig.subplot_mosaic([["mtf", "snr"], ["de", "de"]])
    for key, ax in axes.items():
        ax.legend(handles=CHARTS[key](ax, designs), fontsize=6, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                  borderaxespad=0.0, title=LEGEND_TITLES.get(key), title_fontsize=6)


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


def measure_and_draw(project, pinned: dict | None, chart_px: tuple[int, int], chart: str = "mtf",
                     label: str | None = None):
    """camera_metrics of the project and one chart of it (draw_chart) beside the pinned design's
    (its metrics, with their 'label'), the project's labelled `label` (the window's Metrics panel
    runs this in a worker process). Returns (metrics, chart RGBA, seconds)."""
    import time

    from workbench.metrics.frame import camera_metrics
    t0 = time.perf_counter()
    metrics = camera_metrics(project)
    designs = [metrics] if pinned is None else [pinned, {**metrics, "label": label}]
    rgba = chart_rgba(lambda fig: draw_chart(fig, designs, chart), *chart_px)
    return metrics, rgba, time.perf_counter() - t0

