"""Metric charts stay readable at the Metrics dock's width (issue 32, item 8): each chart alone at
the dock's size and the command line's three-panel figure have titles that fit and do not
overlap, and legends outside the data; A and B are named by what differs between them."""
from __future__ import annotations

import pytest
from chart_checks import assert_readable
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from workbench.metrics.charts import CHARTS, draw_chart, draw_metrics, legend_columns
from workbench.project import difference_labels, load_project

DOCK_CHART_PX = (520, 330)          # a chart tab of the Metrics dock at 1280×800 (its default width: 538 px)


@pytest.fixture(scope="module")
def designs():
    """camera_metrics of the paper camera (small) as A and with 1.5 µm pixels as B, labelled."""
    from workbench.metrics.frame import camera_metrics
    base = load_project("paper_camera")
    a = base.updated(sensor=base.sensor.updated(rows=120, cols=160))
    b = a.updated(sensor=a.sensor.updated(pixel_pitch_um=1.5))
    label_a, label_b = difference_labels(a, b)
    return [{**camera_metrics(a, noise_draws=1), "label": label_a},
            {**camera_metrics(b, noise_draws=1), "label": label_b}]


def drawn(draw, width_px: int, height_px: int, dpi: float = 100.0) -> Figure:
    fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi, layout="constrained")
    draw(fig)
    FigureCanvasAgg(fig).draw()
    return fig


def legend_texts(fig) -> list[str]:
    return [t.get_text() for leg in list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
            for t in leg.get_texts()]


def test_a_and_b_are_named_by_what_differs():
    a = load_project("paper_camera")
    b = a.updated(sensor=a.sensor.updated(pixel_pitch_um=1.5))
    assert difference_labels(a, b) == ("A: pixel_pitch_um 3", "B: pixel_pitch_um 1.5")
    c = b.updated(sensor=b.sensor.updated(read_noise_V=0.002, bit_depth=10), isp=b.isp.updated(demosaic="malvar2004"))
    label_a, label_b = difference_labels(a, c)
    assert label_a != label_b and label_b.startswith("B: ") and label_b.endswith("+2 more"), label_b
    assert difference_labels(a, a) == ("A: paper_camera", "B: paper_camera (same design)")
    assert difference_labels(a, a.updated(name="other")) == ("A: paper_camera", "B: other")


@pytest.mark.parametrize("chart", list(CHARTS))
def test_each_chart_at_the_dock_size_fits_its_title_and_keeps_its_legend_off_the_data(designs, chart):
    """Before: one figure of three panels at this size, titles overlapping, legends on the curves,
    and A and B both 'paper_camera'."""
    fig = drawn(lambda f: draw_chart(f, designs, chart), *DOCK_CHART_PX)
    assert_readable(fig)
    texts = " | ".join(legend_texts(fig))
    assert "A: pixel_pitch_um 3" in texts and "B: pixel_pitch_um 1.5" in texts, texts


def test_the_command_line_figure_keeps_its_legends_beside_the_data(designs):
    for shown in (designs, designs[:1]):
        fig = Figure(figsize=(11, 8), layout="constrained")        # as write_metrics and compare_designs draw it
        draw_metrics(fig, shown)
        FigureCanvasAgg(fig).draw()
        assert_readable(fig)


def test_legend_columns_fit_the_width():
    labels = ["raw R: MTF50 0.555 → 0.559"] * 4 + ["pixel aperture (model): MTF50 0.603 → 0.603"] * 4
    assert legend_columns(labels, 20.0) == 3
    assert legend_columns(labels, 5.1) == 2
    assert legend_columns(labels, 2.0) == 1
