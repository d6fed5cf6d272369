"""Contact sheet: city frames rendered through the project's camera (lens level, sensor, ISP → sRGB),
tiled in a grid with the amodal boxes of the road users drawn over them, a class legend, and a
caption per tile (scene, lighting, features switched on, road users, sampling, render time,
exposure, clipping).

Tiles are the simulated camera's sRGB output, not the render's colorimetric preview: what a
detector would get. Each project is rendered at width × height by binning its sensor (pixel
pitch × cols / width, so the horizontal field of view stays the project's) at a fixed spp.

Geometry (what the test checks): the sheet is `GAP_PX` + columns × (tile width + GAP_PX) wide;
tile k sits at column k % columns, row k // columns, its top-left pixel at
(GAP_PX + col · (tile_w + GAP_PX), header_px + row · (tile_h + caption_px + GAP_PX)). A box
(x, y, w, h) in label pixels (COCO: edges of the covered pixels) is drawn on the tile as the
outline of the tile pixels it touches, ⌊x·s⌋ … ⌈(x + w)·s⌉ − 1 (s = tile size / label size per
axis), 2 px wide for boxes a given rule keeps (`keep`; the command passes the detection
experiments' rule, detect/data.keep_box; none given: all kept), 1 px for the others; objects
with no visible pixel are not drawn.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from workbench.errors import InvalidValueError, ParameterError
from workbench.datasets.stats import CLASSES_OF_INTEREST
from workbench.files import json_text

# One colour per road-user class (RGB), chosen to stand out from grey streets and blue skies.
MAX_FRAMES_PER_SCENE = 64
MAX_TILE_PX = 4096
MAX_SHEET_PIXELS = 2 ** 28                # 268 Mpx: the composed sheet is held in memory as RGB
CLASS_COLOURS = {"car": (255, 48, 48), "pedestrian": (0, 230, 255), "bus": (255, 210, 0), "truck": (210, 90, 255)}
GAP_PX = 4
FONT_PX = 10
LINE_PX = 12
CAPTION_LINES = 5
BACKGROUND = (24, 24, 24)
TEXT = (230, 230, 230)


@dataclass
class SheetTile:
    """One frame for the sheet: its sRGB image (H×W×3 in [0, 1]), labels, caption lines and what
    the JSON records about it."""

    srgb: np.ndarray
    labels: object                      # workbench.render.labels.Labels
    caption: list[str]
    record: dict = field(default_factory=dict)


@dataclass(frozen=True)
class SheetLayout:
    """Pixel geometry of a composed sheet (see the module docstring)."""

    tile_hw: tuple[int, int]
    columns: int
    rows: int
    header_px: int
    caption_px: int

    @property
    def size_wh(self) -> tuple[int, int]:
        th, tw = self.tile_hw
        return (GAP_PX + self.columns * (tw + GAP_PX),
                self.header_px + self.rows * (th + self.caption_px + GAP_PX))

    def tile_origin(self, k: int) -> tuple[int, int]:
        """(x, y) of tile k's top-left pixel on the sheet."""
        th, tw = self.tile_hw
        col, row = k % self.columns, k // self.columns
        return GAP_PX + col * (tw + GAP_PX), self.header_px + row * (th + self.caption_px + GAP_PX)


def box_on_tile(bbox_xywh: Sequence[int], label_hw: tuple[int, int], tile_hw: tuple[int, int]
                ) -> tuple[int, int, int, int]:
    """A label box (x, y, w, h in label pixels) as the inclusive pixel rectangle (x0, y0, x1, y1)
    it covers on a tile of tile_hw."""
    x, y, w, h = bbox_xywh
    sy, sx = tile_hw[0] / label_hw[0], tile_hw[1] / label_hw[1]
    x0, y0 = math.floor(x * sx), math.floor(y * sy)
    return x0, y0, max(math.ceil((x + w) * sx) - 1, x0), max(math.ceil((y + h) * sy) - 1, y0)


KeepRule = Callable[[dict, int], bool]       # (COCO annotation with occlusion/truncation, image rows) → kept


def drawn_objects(labels, classes: Sequence[str] = CLASSES_OF_INTEREST,
                  keep: KeepRule | None = None) -> list[tuple[object, bool]]:
    """(object, kept by `keep`) for every object of `classes` with a visible pixel."""
    rows = labels.shape[0]
    return [(o, keep is None or bool(keep({"bbox": list(o.bbox_xywh), "occlusion": o.occlusion,
                                          "truncation": o.truncation}, rows)))
            for o in labels.objects if o.class_name in classes and o.visible_px > 0]


def _font(size_px: int):
    from PIL import ImageFont
    return ImageFont.load_default(size=size_px)


def _fit(draw, text: str, font, width_px: int) -> str:
    """`text`, cut short with '…' where it would be wider than width_px."""
    if draw.textlength(text, font=font) <= width_px:
        return text
    while text and draw.textlength(text + "…", font=font) > width_px:
        text = text[:-1]
    return text + "…"


def compose_sheet(tiles: Sequence[SheetTile], columns: int, title: str,
                  classes: Sequence[str] = CLASSES_OF_INTEREST, keep: KeepRule | None = None):
    """(PIL image, SheetLayout): the tiles in a grid of `columns`, amodal boxes of `classes`
    drawn per the module docstring (line width by `keep`), a title and class legend on top,
    captions under the tiles."""
    from PIL import Image, ImageDraw
    if not tiles:
        raise InvalidValueError("a contact sheet needs at least one tile")
    shapes = {t.srgb.shape[:2] for t in tiles}
    if len(shapes) != 1:
        raise InvalidValueError(f"tiles differ in size: {sorted(shapes)}")
    tile_hw = shapes.pop()
    columns = max(1, min(columns, len(tiles)))
    layout = SheetLayout(tile_hw, columns, -(-len(tiles) // columns), header_px=2 * LINE_PX + 2 * GAP_PX,
                         caption_px=CAPTION_LINES * LINE_PX + 2)
    sheet = Image.new("RGB", layout.size_wh, BACKGROUND)
    draw = ImageDraw.Draw(sheet)
    font = _font(FONT_PX)
    draw.text((GAP_PX, GAP_PX), title, fill=TEXT, font=font)
    x = GAP_PX
    for name in classes:                          # legend: a swatch and the class name
        colour = CLASS_COLOURS.get(name, TEXT)
        y = GAP_PX + LINE_PX + 1
        draw.rectangle([x, y + 2, x + 8, y + 9], fill=colour)
        draw.text((x + 11, y), name, fill=colour, font=font)
        x += 11 + int(draw.textlength(name, font=font)) + 10
    draw.text((x, GAP_PX + LINE_PX + 1), "amodal boxes of visible objects" + (
        "; 2 px: kept by the detection rule, 1 px: ignored" if keep is not None else ""), fill=TEXT, font=font)
    for k, tile in enumerate(tiles):
        x0, y0 = layout.tile_origin(k)
        rgb = np.round(np.clip(np.nan_to_num(tile.srgb), 0.0, 1.0) * 255).astype(np.uint8)
        sheet.paste(Image.fromarray(rgb), (x0, y0))
        for obj, kept in drawn_objects(tile.labels, classes, keep):
            bx0, by0, bx1, by1 = box_on_tile(obj.amodal_bbox_xywh, tile.labels.shape, tile_hw)
            draw.rectangle([x0 + bx0, y0 + by0, x0 + bx1, y0 + by1],
                           outline=CLASS_COLOURS.get(obj.class_name, TEXT), width=2 if kept else 1)
        for i, line in enumerate(tile.caption[:CAPTION_LINES]):
            draw.text((x0, y0 + tile_hw[0] + 1 + i * LINE_PX), _fit(draw, line, font, tile_hw[1]), fill=TEXT,
                      font=font)
    return sheet, layout


def to_palette(sheet, colours: int, exact: Sequence[tuple[int, int, int]]):
    """The sheet as a palette image of `colours` entries (a PNG about a third the size of an RGB
    one for noisy frames): a median-cut palette of the sheet, no dithering, plus the `exact`
    colours, every pixel mapped to its nearest entry, so overlays in those colours stay exact."""
    from PIL import Image
    exact = list(dict.fromkeys(tuple(c) for c in exact))
    if not len(exact) < colours <= 256:
        raise InvalidValueError(f"a palette of {colours} colours must hold the {len(exact)} exact ones and more, "
                         "and at most 256")
    adaptive = sheet.quantize(colors=colours - len(exact), method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    entries = adaptive.getpalette()[:3 * (colours - len(exact))] + [v for c in exact for v in c]
    reference = Image.new("P", (1, 1))
    reference.putpalette(entries + entries[:3] * (256 - len(entries) // 3))    # pad with a used entry
    return sheet.quantize(palette=reference, dither=Image.Dither.NONE)


def sheet_project(project, width: int, height: int, spp: int, sensor_noise: bool = True):
    """The project at width × height (sensor binned: pixel pitch × cols / width, same horizontal
    field of view) rendered at a fixed `spp`; sensor_noise False: the sensor's noise_flag 0 (gain,
    offset, clipping and quantisation, no noise), so what grain is left is the renderer's; a size
    or spp the project refuses is a one-line ParameterError naming the option."""
    for name, value, lo, hi in (("width", width, 8, MAX_TILE_PX), ("height", height, 8, MAX_TILE_PX),
                                ("spp", spp, 1, 1 << 16)):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise ParameterError(name, value, f"an integer from {lo} to {hi:,}")
    sensor = project.sensor
    pitch_um = sensor.pixel_pitch_um * sensor.cols / width
    if pitch_um > 100.0:
        raise ParameterError("--width", width, f"too small for {project.name}: binning its {sensor.cols} columns "
                                               f"to {width} needs a {pitch_um:.0f} µm pixel (at most 100 µm)")
    noise = {} if sensor_noise else {"noise_flag": 0}
    return project.updated(sensor=sensor.updated(rows=height, cols=width, pixel_pitch_um=pitch_um, **noise),
                           render=project.render.updated(spp=spp, target_rel_error=None, shot_noise_ratio=None))


def lighting_caption(project) -> str:
    """The project's lighting and weather (and a tunnel) in a few words."""
    world, day = project.render.world, project.render.daylight
    if world.lighting == "night":
        n = world.night
        text = f"night: {n.lamp_kind} lamps" + (", vehicle lights" if n.vehicle_lights else "")
    elif day.sky_model == "overcast":
        text = f"overcast (CIE), {day.overcast_transmittance:g} of clear sky"
    else:
        sun = (f"sun at {day.time_of_day_h:g} h" if day.time_of_day_h is not None
               else f"sun el {day.sun_elevation_deg:g}° az {day.sun_azimuth_deg:g}°")
        text = f"{sun}, {day.sky_model} sky"
    if world.fog is not None:
        text += f"; fog V {world.fog.visibility_m:g} m ({world.fog.model})"
    tunnel = getattr(project.city, "tunnel", None)
    if tunnel is not None:
        text += f"; tunnel {tunnel.length_m:g} m, {tunnel.luminaire_kind} lights"
    return text


def features_caption(project) -> str:
    """The scene features that are switched on (issue 8: each is a switch)."""
    world = project.render.world
    words = [f"{getattr(project.city, 'asset_detail', 'simple')} assets", f"{world.materials} surfaces"]
    if world.materials == "procedural" and world.wet_road_fraction > 0:
        words[-1] += f" ({100 * world.wet_road_fraction:.0f} % wet)"
    words += ["glass panes"] if world.glass == "dielectric" else []
    words += ["clear coat"] if world.paint == "clearcoat" else []
    return ", ".join(words)


def _duration(seconds: float) -> str:
    return f"{seconds:.3g} s" if seconds >= 1.0 else f"{seconds * 1e3:.3g} ms"


def camera_tile(project, index: int, renderer: Callable | None = None, keep: KeepRule | None = None) -> SheetTile:
    """Frame `index` of a city project rendered (renderer(project, seeds) → FrameData, default
    render_city_frame), then exposed by the project's sensor (temporal noise seeded by the frame's
    render seed) and developed by its ISP to sRGB, with its caption and record."""
    from workbench.isp import sensor_image_to_srgb
    from workbench.render.city_frame import frame_optical_image, project_frame_seeds, render_city_frame
    from workbench.sensor import irradiance_to_sensor_image
    seeds = project_frame_seeds(project, index)
    t0 = time.perf_counter()
    data = (renderer or render_city_frame)(project, seeds)
    render_s = time.perf_counter() - t0
    image = irradiance_to_sensor_image(frame_optical_image(data), project.sensor, seed=seeds.render)
    isp = sensor_image_to_srgb(image, project.isp)
    camera_s = time.perf_counter() - t0 - render_s
    objects = drawn_objects(data.labels, keep=keep)
    counts = {c: sum(o.class_name == c for o, _ in objects) for c in CLASSES_OF_INTEREST}
    exposure_s = float(np.mean(image.exposure_s))
    clipped = float(np.mean(image.dn >= image.max_dn))
    spp = data.meta.get("spp", project.render.spp)
    lighting, features = lighting_caption(project), features_caption(project)
    caption = [f"{project.name} #{index}  ({image.pattern})", lighting, features,
               "  ".join(f"{'ped' if c == 'pedestrian' else c} {n}" for c, n in counts.items()),
               f"{spp} spp {render_s:.1f} s  t {_duration(exposure_s)}  clip {100 * clipped:.1f} %"
               + ("" if project.sensor.noise_flag else "  no sensor noise")]
    record = {"project": project.name, "frame": index, "seeds": asdict(seeds), "lighting": lighting,
              "features": features, "cfa": image.pattern, "spp": spp, "render_s": round(render_s, 3),
              "sensor_isp_s": round(camera_s, 3), "sensor_noise_flag": project.sensor.noise_flag,
              "exposure_s": exposure_s, "clipped_fraction": clipped,
              "visible_objects_of_interest": counts,
              "kept_objects_of_interest": {c: sum(o.class_name == c and k for o, k in objects)
                                           for c in CLASSES_OF_INTEREST},
              "boxes": [{"class": o.class_name, "instance_id": o.instance_id,
                         "amodal_bbox_xywh": list(o.amodal_bbox_xywh), "bbox_xywh": list(o.bbox_xywh),
                         "distance_m": round(o.distance_m, 2), "kept": kept} for o, kept in objects],
              "isp_notes": list(isp.notes or [])}
    return SheetTile(isp.srgb, data.labels, caption, record)


def write_contact_sheet(projects: Sequence, frames_per_scene: int, out_png: str | Path, *, width: int = 320,
                        height: int = 240, spp: int = 32, columns: int = 4, renderer: Callable | None = None,
                        keep: KeepRule | None = None, colours: int | None = None, sensor_noise: bool = True,
                        on_tile: Callable[[int, int, SheetTile], None] | None = None) -> tuple[Path, Path]:
    """Render frames 0 … frames_per_scene − 1 of each city project (camera_tile, at width × height,
    fixed spp: sheet_project), compose them (compose_sheet) and write the PNG and a JSON record
    beside it (same name, .json), each atomically and only once every frame has rendered: a
    failed render writes nothing. keep: which boxes are drawn 2 px wide (module docstring);
    colours: store a palette PNG of that many colours (to_palette; class, text and background
    colours exact) instead of RGB; sensor_noise False: every sensor without its noise (sheet_project);
    on_tile(k, total, tile) is called after each frame."""
    import io

    from workbench.files import atomic_write_files
    out_png = Path(out_png)
    if out_png.suffix.lower() != ".png":
        from workbench.errors import OutputPathError
        raise OutputPathError(out_png, "must name a .png file")
    if not 1 <= frames_per_scene <= MAX_FRAMES_PER_SCENE:
        raise ParameterError("frames_per_scene", frames_per_scene, f"an integer from 1 to {MAX_FRAMES_PER_SCENE}")
    sheet_px = len(projects) * frames_per_scene * width * height
    if sheet_px > MAX_SHEET_PIXELS:
        raise ParameterError("frames_per_scene", frames_per_scene,
                             f"a sheet of at most {MAX_SHEET_PIXELS:,} pixels ({len(projects)} projects × "
                             f"{frames_per_scene} frames × {width}×{height} px is {sheet_px:,}); fewer frames or "
                             "smaller tiles")
    if colours is not None and not len(CLASS_COLOURS) + 2 < colours <= 256:
        raise InvalidValueError(f"colours must lie in {len(CLASS_COLOURS) + 3}…256, got {colours}")
    sized = [sheet_project(p, width, height, spp, sensor_noise) for p in projects]
    total = len(sized) * frames_per_scene
    tiles, t0 = [], time.perf_counter()
    for p in sized:
        for i in range(frames_per_scene):
            tiles.append(camera_tile(p, i, renderer, keep))
            if on_tile is not None:
                on_tile(len(tiles), total, tiles[-1])
    wall_s = time.perf_counter() - t0
    title = (f"{total} frames, {width}x{height}, {spp} spp (fixed, so noise differs by scene), through each "
             f"project's lens, sensor{'' if sensor_noise else ' (noise off)'} and ISP")
    sheet, layout = compose_sheet(tiles, columns, title, keep=keep)
    if colours is not None:
        sheet = to_palette(sheet, colours, [*CLASS_COLOURS.values(), TEXT, BACKGROUND])
    buf = io.BytesIO()
    sheet.save(buf, format="PNG", optimize=True)
    record = {"png": out_png.name, "width": width, "height": height, "spp": spp,
              "frames_per_scene": frames_per_scene, "projects": [p.name for p in sized],
              "columns": layout.columns, "palette_colours": colours, "sheet_size_wh": list(layout.size_wh), "wall_s": round(wall_s, 1),
              "sensor_binning": "pixel pitch × cols / width: the project's horizontal field of view",
              "tiles": [{**t.record, "origin_xy": list(layout.tile_origin(k))} for k, t in enumerate(tiles)]}
    json_path = out_png.with_suffix(".json")
    atomic_write_files({out_png: buf.getvalue(),                 # both or neither: no record of a missing sheet
                        json_path: (json_text(record) + "\n").encode()})
    return out_png, json_path
