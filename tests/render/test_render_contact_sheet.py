"""Contact sheet (datasets/contact_sheet.py, `workbench contact-sheet`): the tile grid has the stated
size, each road user's amodal box is drawn in its class colour where its label box lies (scaled to
the tile), and a failed render writes nothing."""
import json

import numpy as np
import pytest
from PIL import Image

from workbench.cli import main
from workbench.project import load_project
from workbench.render import city_frame
from workbench.datasets.contact_sheet import (BACKGROUND, CAPTION_LINES, CLASS_COLOURS, GAP_PX, LINE_PX, TEXT,
                                            SheetTile, compose_sheet, to_palette, write_contact_sheet)
from workbench.render.labels import Labels, ObjectLabel

W, H = 48, 36
HEADER_PX = 2 * LINE_PX + 2 * GAP_PX              # title line + legend line
CAPTION_PX = CAPTION_LINES * LINE_PX + 2


def origin(k: int, columns: int, tile_h: int = H, tile_w: int = W) -> tuple[int, int]:
    """Top-left pixel of tile k, from the layout the module docstring states."""
    return (GAP_PX + (k % columns) * (tile_w + GAP_PX),
            HEADER_PX + (k // columns) * (tile_h + CAPTION_PX + GAP_PX))


def outline(x0, y0, x1, y1):
    """Pixels on the 1-px outline of the inclusive rectangle."""
    xs, ys = np.arange(x0, x1 + 1), np.arange(y0, y1 + 1)
    return ([(x, y0) for x in xs] + [(x, y1) for x in xs] + [(x0, y) for y in ys] + [(x1, y) for y in ys])


def test_sheet_of_two_scenes_draws_each_label_box_on_its_tile(tmp_path):
    seen = []

    def renderer(project, seeds):                  # the real render; keep its labels as the truth
        data = city_frame.render_city_frame(project, seeds)
        seen.append(data.labels)
        return data
    projects = [load_project("city_detection_quick"), load_project("city_day_clear_sky")]
    png, record_path = write_contact_sheet(projects, 1, tmp_path / "cs.png", width=W, height=H, spp=2,
                                           columns=2, renderer=renderer)
    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape == (HEADER_PX + H + CAPTION_PX + GAP_PX, GAP_PX + 2 * (W + GAP_PX), 3)
    record = json.loads(record_path.read_text())
    assert [t["project"] for t in record["tiles"]] == ["city_detection_quick", "city_day_clear_sky"]
    assert [tuple(t["origin_xy"]) for t in record["tiles"]] == [origin(0, 2), origin(1, 2)]
    assert [t["spp"] for t in record["tiles"]] == [2, 2]
    drawn = 0
    for k, labels in enumerate(seen):
        assert labels.shape == (H, W)
        ox, oy = origin(k, 2)
        boxes = [o for o in labels.objects if o.class_name in CLASS_COLOURS and o.visible_px > 0]
        assert len(record["tiles"][k]["boxes"]) == len(boxes)
        for j, o in enumerate(boxes):
            x, y, w, h = o.amodal_bbox_xywh                  # tile = label grid here: scale 1
            rect = (ox + x, oy + y, ox + x + w - 1, oy + y + h - 1)
            colours = [tuple(img[py, px]) for px, py in outline(*rect)]
            colour = CLASS_COLOURS[o.class_name]
            if j == len(boxes) - 1:                          # drawn last: nothing covers its outline
                assert all(c == colour for c in colours), (o, set(colours))
            else:
                assert colour in colours
            drawn += 1
    assert drawn >= 1                                        # the target poses put road users in view


def _label(instance_id, name, box, visible_px=20, occlusion=0.0):
    return ObjectLabel(instance_id, 1, name, box, box, visible_px, visible_px, occlusion, False, 0.0, 10.0)


def test_boxes_are_scaled_from_the_label_grid_and_kept_boxes_drawn_thicker():
    """Labels on a 2× finer grid than the tile (as with scene.oversample 2): a box covers the tile
    pixels it touches, ⌊x0 / 2⌋ … ⌈x1 / 2⌉ − 1; the keep rule picks 2-px outlines."""
    objects = [_label(1, "car", (10, 8, 30, 20)), _label(2, "pedestrian", (60, 20, 9, 40), occlusion=0.9),
               _label(3, "tree", (2, 2, 20, 20)), _label(4, "bus", (70, 2, 10, 10), visible_px=0)]
    z = np.zeros((72, 96))
    labels = Labels(z, z, z.astype(np.int32), z.astype(np.int32), objects, {})
    tile = SheetTile(np.full((H, W, 3), 0.5), labels, ["a caption"])
    sheet, layout = compose_sheet([tile], 3, "title", keep=lambda ann, rows: ann["occlusion"] < 0.5)
    img = np.asarray(sheet)
    assert layout.size_wh == (GAP_PX + W + GAP_PX, HEADER_PX + H + CAPTION_PX + GAP_PX) == sheet.size
    ox, oy = origin(0, 1)
    car, ped = CLASS_COLOURS["car"], CLASS_COLOURS["pedestrian"]
    assert tuple(img[oy + 4, ox + 5]) == car and tuple(img[oy + 4 + 1, ox + 5 + 1]) == car      # 2 px: kept
    assert tuple(img[oy + 14 - 1, ox + 20 - 1]) == car and tuple(img[oy + 14 - 2, ox + 20 - 2]) == car
    assert tuple(img[oy + 10, ox + 30]) == ped and tuple(img[oy + 10 + 1, ox + 30 + 1]) != ped  # 1 px: ignored
    assert tuple(img[oy + 29, ox + 34]) == ped and tuple(img[oy + 28, ox + 33]) != ped    # ⌈34.5⌉ − 1
    tile_px = {tuple(c) for c in img[oy:oy + H, ox:ox + W].reshape(-1, 3)}
    assert CLASS_COLOURS["bus"] not in tile_px                 # not visible: not drawn
    assert len(tile_px - {car, ped, (128, 128, 128)}) == 0     # the tree is no road user


def test_palette_sheet_keeps_the_overlay_colours_exact():
    rng = np.random.default_rng(0)
    z = np.zeros((H, W))
    boxes = [_label(k + 1, name, (4 + 10 * k, 4, 8, 20)) for k, name in enumerate(CLASS_COLOURS)]
    tiles = [SheetTile(rng.uniform(0, 1, (H, W, 3)), Labels(z, z, z.astype(np.int32), z.astype(np.int32), boxes, {}),
                       ["noise"]) for _ in range(2)]
    sheet, _ = compose_sheet(tiles, 2, "title")
    exact = [*CLASS_COLOURS.values(), TEXT, BACKGROUND]
    small = to_palette(sheet, 16, exact)
    assert small.mode == "P" and len(small.getcolors()) <= 16
    rgb, ref = np.asarray(small.convert("RGB")), np.asarray(sheet)
    for c in exact:                                  # every pixel of an exact colour keeps it
        at = np.all(ref == c, axis=-1)
        assert (at.any() or c == TEXT) and np.all(rgb[at] == c)      # small text is all anti-aliased
    with pytest.raises(ValueError):
        to_palette(sheet, 6, exact)


def test_a_failed_render_leaves_no_sheet(tmp_path, monkeypatch, capsys):
    out = tmp_path / "cs.png"
    out.write_bytes(b"an older sheet")
    calls = []
    real = city_frame.render_city_frame

    def fails_second(project, seeds, on_progress=None):
        calls.append(seeds.index)
        if len(calls) == 2:
            from workbench.errors import StageError
            raise StageError("scene", "render failed on purpose")
        return real(project, seeds)
    monkeypatch.setattr(city_frame, "render_city_frame", fails_second)
    rc = main(["contact-sheet", "city_day_clear_sky", "--out", str(out), "--frames-per-scene", "2",
               "--width", str(W), "--height", str(H), "--spp", "2"])
    assert rc == 2 and "render failed on purpose" in capsys.readouterr().err
    assert calls == [0, 1]
    assert out.read_bytes() == b"an older sheet"
    assert _files(tmp_path) == ["cs.png"]                                 # no JSON, no temporary


def _files(folder) -> list[str]:
    """The files in a folder but the sheet's lock (.cs.png.lock: one writer per sheet)."""
    return sorted(p.name for p in folder.iterdir() if not p.name.endswith(".lock"))


@pytest.mark.parametrize("flag, value", [("--spp", "0"), ("--frames-per-scene", "0"), ("--width", "2"),
                                         ("--colours", "6"), ("--colours", "257")])
def test_bad_options_are_refused(tmp_path, flag, value, capsys):
    assert main(["contact-sheet", "city_day_clear_sky", "--out", str(tmp_path / "cs.png"), flag, value]) == 2
    assert flag in capsys.readouterr().err and not any(tmp_path.iterdir())


@pytest.mark.parametrize("option,value", [("--frames-per-scene", "100000"), ("--width", "99999"),
                                          ("--height", "3"), ("--spp", "10000000"), ("--columns", "0")])
def test_options_out_of_range_are_one_line_errors(tmp_path, capsys, option, value):
    rc = main(["contact-sheet", "city_day_clear_sky", "--out", str(tmp_path / "cs.png"), option, value])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and option in err and "\n" not in err and "validation error" not in err
    assert not list(tmp_path.iterdir())


def test_a_sheet_and_its_record_are_written_together_or_not_at_all(tmp_path, monkeypatch, capsys):
    """A disk that fills up while the record is staged leaves the older sheet and record as they
    were, and no temporary file (the PNG is never replaced alone)."""
    import workbench.files as files
    out = tmp_path / "cs.png"
    out.write_bytes(b"older sheet")
    out.with_suffix(".json").write_text("older record")
    real = files._write_all

    def full_disk(fd, data):
        if data.startswith(b"{"):                      # the record, staged after the sheet
            raise OSError(28, "No space left on device")
        real(fd, data)
    monkeypatch.setattr(files, "_write_all", full_disk)
    rc = main(["contact-sheet", "city_day_clear_sky", "--out", str(out), "--frames-per-scene", "1",
               "--width", str(W), "--height", str(H), "--spp", "2"])
    err = capsys.readouterr().err
    assert rc == 2 and "cs.json" in err and "No space left" in err
    assert out.read_bytes() == b"older sheet" and out.with_suffix(".json").read_text() == "older record"
    assert _files(tmp_path) == ["cs.json", "cs.png"]


def test_with_the_sensor_noise_off_two_captures_of_one_render_are_the_same():
    """`--sensor-noise off` (issue 33: tell the renderer's grain from the sensor's): the tile of one
    rendered frame, exposed with two different temporal-noise seeds, is the same image with the
    sensor's noise off and differs with it on; the caption and record say so."""
    from workbench.datasets.contact_sheet import camera_tile, sheet_project
    cache = {}

    def renderer(project, seeds):                  # one render, whatever the frame's seeds
        if "data" not in cache:
            cache["data"] = city_frame.render_city_frame(project, seeds)
        return cache["data"]
    tiles = {}
    for noise in (True, False):
        project = sheet_project(load_project("city_night"), W, H, 2, sensor_noise=noise)
        tiles[noise] = [camera_tile(project, i, renderer) for i in (0, 1)]
    assert not np.array_equal(tiles[True][0].srgb, tiles[True][1].srgb)
    np.testing.assert_array_equal(tiles[False][0].srgb, tiles[False][1].srgb)
    assert tiles[False][0].record["sensor_noise_flag"] == 0 and "no sensor noise" in tiles[False][0].caption[-1]
    assert tiles[True][0].record["sensor_noise_flag"] == 2 and "no sensor noise" not in tiles[True][0].caption[-1]
