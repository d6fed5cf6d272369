"""Hypothesis strategies and checks for fuzzing project documents and lens files.

A project document is a sample project mutated 1–3 times (a value replaced by a wrong type, NaN,
±inf, an extreme or odd unicode, or scaled; a field deleted; an unknown field added; rarely the
text truncated). `check_document` loads it and, if it loads, simulates it at 16×12 pixels (≤ 64 spp) and
checks that every output is finite and that save → load gives the same project; it returns the
outcome and fails on anything else (another exception, a refusal that names no field, NaN)."""
from __future__ import annotations

import json
import math
import contextlib
import io
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from workbench.errors import InputFileError, ParameterError, WorkbenchError
from workbench.optics.lens.io import LENS_DIR, lens_to_dat
from workbench.project import PROJECTS_DIR, load_project, save_project

SAMPLES = {p.stem: json.loads(p.read_text()) for p in sorted(PROJECTS_DIR.glob("*.json"))}
CHART_SAMPLES = tuple(k for k, v in SAMPLES.items() if v["scene"]["kind"] != "city")
SMALL_ROWS, SMALL_COLS = 12, 16
MAX_FUZZ_SPP = 64

ODD_STRINGS = ["", " ", "\u0000", "\ud800", "\u202e" + "evil", "😀" * 3, "é" * 200, "x" * 5000, "\n\r\t", "NaN", "inf",
               "0.01", "120", "true", "../../etc/passwd", "/etc/passwd", "C:\\x", "null"]
SPECIAL_VALUES = [math.nan, math.inf, -math.inf, 0, 0.0, -0.0, -1, 1, 5e-324, 1e-300, -1e308, 1e308,
                  2 ** 31, 2 ** 63, 2 ** 64, -2 ** 63, 10 ** 30, True, False, None, [], {}, [1, 2], [[1]],
                  {"a": 1}, [math.nan], [0.0, math.inf]]
NASTY = st.one_of(st.sampled_from(SPECIAL_VALUES), st.sampled_from(ODD_STRINGS),
                  st.text(max_size=12), st.integers(min_value=-2 ** 70, max_value=2 ** 70),
                  st.floats(allow_nan=True, allow_infinity=True),
                  st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4))


def _paths(node, prefix=()) -> list[tuple]:
    """Every location in a decoded JSON document (containers and leaves), the root excluded."""
    out = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        out.append(prefix + (key,))
        out.extend(_paths(value, prefix + (key,)))
    return out


def _parent(doc, path):
    for key in path[:-1]:
        doc = doc[key]
    return doc


@st.composite
def project_texts(draw, samples=tuple(SAMPLES)) -> tuple[str, str, list[str]]:
    """(sample name, document text, the mutations applied)."""
    name = draw(st.sampled_from(sorted(samples)))
    doc = json.loads(json.dumps(SAMPLES[name]))
    applied = []
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(doc)
        path = draw(st.sampled_from(paths))
        parent, key = _parent(doc, path), path[-1]
        op = draw(st.sampled_from(["nasty", "nasty", "scale", "scale", "scale", "delete", "add"]))
        if op == "scale" and isinstance(parent[key], (int, float)) and not isinstance(parent[key], bool):
            factor = draw(st.sampled_from([-1, 0, 0.5, 2, 10, 1e3, 1e-3]))
            value = parent[key] * factor
            parent[key] = int(value) if isinstance(parent[key], int) else value
        elif op == "delete" and isinstance(parent, dict):
            del parent[key]
        elif op == "add":
            target = parent if isinstance(parent, dict) else doc
            target[draw(st.sampled_from(ODD_STRINGS[1:] + ["extra", "rows", "seed"]))] = draw(NASTY)
        else:
            parent[key] = draw(NASTY)
        applied.append(f"{op}:{'.'.join(map(str, path))}")
    text = json.dumps(doc, indent=1)
    if draw(st.integers(0, 19)) == 0:
        text = text[: draw(st.integers(0, len(text) - 1))]
        applied.append("truncate")
    return name, text, applied


def _finite(name: str, array) -> None:
    arr = np.asarray(array)
    if arr.dtype.kind in "fc":
        assert np.all(np.isfinite(arr)), f"{name} holds NaN/Inf"


def _cheap_render(render):
    """The render settings with at most MAX_FUZZ_SPP samples per pixel: a scaled-up spp (64 → 64,000)
    is a valid document, checked at load; rendering it in 4,000 chunks would only cost time."""
    cheap = {"max_spp": min(render.max_spp, MAX_FUZZ_SPP)}
    if render.spp is not None:
        cheap["spp"] = min(render.spp, MAX_FUZZ_SPP)
    return render.updated(**cheap)


def check_document(text: str, folder: Path) -> str:
    """Load `text` as a project file; refused → 'refused_field'/'refused_file'; loaded → simulate at
    16×12 and ≤ MAX_FUZZ_SPP spp, check finite outputs and the save round trip → 'simulated' (or 'refused_at_run' for a
    WorkbenchError from a stage). Anything else fails the calling test."""
    from workbench.pipeline import Pipeline
    path = folder / "fuzz.json"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        project = load_project(path)
    except ParameterError as exc:
        assert exc.field and exc.field != "(document)", f"refusal names no field: {exc}"
        assert "\n" not in str(exc)
        return "refused_field"
    except InputFileError as exc:
        assert "\n" not in str(exc)
        return "refused_file"
    saved = save_project(project, folder / "saved.json")
    assert load_project(saved).model_dump() == project.model_dump(), "save → load changed the project"
    small = project.updated(sensor=project.sensor.updated(rows=SMALL_ROWS, cols=SMALL_COLS),
                            render=_cheap_render(project.render))
    try:
        result = Pipeline(small).run()
    except WorkbenchError as exc:
        assert "\n" not in str(exc)
        return "refused_at_run"
    img, isp = result.sensor_image, result.isp
    assert img.dn.shape[:2] == (SMALL_ROWS, SMALL_COLS) and isp.srgb.shape == (SMALL_ROWS, SMALL_COLS, 3)
    for name, array in (("irradiance", result.optical_image.irradiance_photons),
                        ("signal_rate", result.signal_rate_e_per_s), ("electrons", img.electrons),
                        ("volts", img.volts), ("dn", img.dn), ("raw", isp.raw), ("linear", isp.linear),
                        ("srgb", isp.srgb), ("exposure_s", img.exposure_s)):
        _finite(name, array)
    return "simulated"


# ---------------------------------------------------------------- lens files
LENS_TOKENS = ["nan", "inf", "-inf", "0", "-5", "1e308", "-1e308", "100000000", "UNOBTAINIUM", "", "\x00",
               "PARM", "SURF", "STOP", "[", "{", '"', "1e-320"]
ZMX = """VERS 190513 80 123457 L123457
UNIT MM X W X CM MR CPMM
SURF 0
  TYPE STANDARD
  DISZ INFINITY
SURF 1
  TYPE STANDARD
  CURV 0.02
  DISZ 5
  GLAS N-BK7 1 0 1.5168 64.17 0 0 0 0 0 0
  DIAM 10
SURF 2
  STOP
  TYPE STANDARD
  DISZ 2
  DIAM 8
SURF 3
  TYPE EVENASPH
  CURV -0.01
  PARM 2 1e-5
  DISZ 80
  DIAM 10
SURF 4
  TYPE STANDARD
"""


def _lens_bases() -> list[tuple[str, str]]:
    from workbench.optics.lens.io import load_lens
    bases = [(".zmx", ZMX)]
    for p in sorted(LENS_DIR.glob("*.json")):
        bases.append((".json", p.read_text()))
        bases.append((".dat", lens_to_dat(load_lens(p))))
    return bases


LENS_BASES = _lens_bases()


@st.composite
def lens_files(draw) -> tuple[str, bytes, list[str]]:
    """(suffix, file bytes, mutations): a shipped lens (or a Zemax sample) with 1–3 mutations."""
    suffix, text = draw(st.sampled_from(LENS_BASES))
    applied = []
    if suffix == ".json" and draw(st.booleans()):
        doc = json.loads(text)
        surf = draw(st.sampled_from(doc["surfaces"]))
        field = draw(st.sampled_from(["radius", "thickness", "semi_aperture", "glass", "ior"]))
        surf[field] = draw(st.one_of(NASTY, st.sampled_from([0, 0.0, -3.0, "UNOBTAINIUM", "1.2/-5"])))
        applied.append(f"surface.{field}")
        text = json.dumps(doc)
    for _ in range(draw(st.integers(0 if applied else 1, 3))):
        op = draw(st.sampled_from(["token", "token", "truncate", "binary", "duplicate_line"]))
        tokens = text.split(" ")
        if op == "token" and tokens:
            i = draw(st.integers(0, len(tokens) - 1))
            tokens[i] = draw(st.sampled_from(LENS_TOKENS))
            text = " ".join(tokens)
        elif op == "truncate" and text:
            text = text[: draw(st.integers(0, len(text) - 1))]
        elif op == "duplicate_line":
            lines = text.splitlines()
            if lines:
                i = draw(st.integers(0, len(lines) - 1))
                text = "\n".join(lines[: i + 1] + lines[i:])
        applied.append(op)
    data = text.encode("utf-8", errors="surrogatepass")
    if "binary" in applied:
        i = draw(st.integers(0, len(data)))
        data = data[:i] + draw(st.binary(min_size=1, max_size=16)) + data[i:]
    return suffix, data, applied


def check_lens_file(suffix: str, data: bytes, folder: Path) -> str:
    """Load a lens file: 'refused' (InputFileError naming it, one line), else 'loaded' and then
    `workbench lens info` on it must succeed or print one error line (no traceback)."""
    from workbench.cli import main
    from workbench.optics.lens.io import load_lens
    path = folder / f"fuzz{suffix}"
    path.write_bytes(data)
    try:
        load_lens(path)
    except InputFileError as exc:
        assert str(exc).startswith(str(path)) and "\n" not in str(exc)
        return "refused"
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["lens", "info", str(path)])
    lines = err.getvalue().strip().splitlines()
    assert code == 0 or (code == 2 and len(lines) == 1 and lines[0].startswith("workbench lens info: error:")), \
        err.getvalue()
    return "loaded" if code == 0 else "loaded_info_refused"
