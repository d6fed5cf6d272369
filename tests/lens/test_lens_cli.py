"""`workbench lens info` and `workbench lens plot`."""
import json

import numpy as np
import pytest
from PIL import Image

from workbench.cli import main


def test_lens_info_json(capsys):
    assert main(["lens", "info", "automotive.2.4mm", "--json", "--max-field-deg", "26.8"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["paraxial"]["efl_mm"] == pytest.approx(2.3761, abs=1e-4)
    rows = s["fields"]
    assert [r["field_deg"] for r in rows] == pytest.approx([0, 13.4, 18.76, 26.8])
    assert rows[0]["relative_illumination"] == 1.0
    ri = [r["relative_illumination"] for r in rows]
    assert all(a > b for a, b in zip(ri, ri[1:]))       # monotone fall-off with field
    cos4 = np.cos(np.radians([r["field_deg"] for r in rows])) ** 4
    assert all(r <= c + 1e-3 for r, c in zip(ri, cos4))  # vignetted lens: at or below cos⁴
    assert all(r["spot_rms_um"] < 3.5 for r in rows)     # paper-scale lens: blur about a pixel


def test_lens_info_text_and_errors(capsys, tmp_path):
    assert main(["lens", "info", "dgauss.50mm"]) == 0
    out = capsys.readouterr().out
    assert "EFL 50.3582 mm" in out and "f/2.030" in out
    assert main(["lens", "info", "nope"]) == 2
    assert "nope" in capsys.readouterr().err


@pytest.mark.slow
def test_lens_plot_writes_pngs(tmp_path, capsys):
    assert main(["lens", "plot", "automotive.2.4mm", "--out", str(tmp_path), "--max-field-deg", "26"]) == 0
    names = {"layout.png", "spots.png", "ray_fans.png", "mtf.png", "distortion.png", "relative_illumination.png"}
    assert names <= {p.name for p in tmp_path.iterdir()}
    for n in names:
        img = np.asarray(Image.open(tmp_path / n).convert("L"))
        assert img.std() > 5  # something was drawn


def test_lens_info_with_sensor_reports_fields_of_view(capsys):
    assert main(["lens", "info", "automotive.2.4mm", "--json", "--sensor-mm", "1.92", "1.44"]) == 0
    s = json.loads(capsys.readouterr().out)
    fov = s["field_of_view"]
    assert fov["horizontal"]["paraxial_deg"] == pytest.approx(44.0, abs=1e-6)
    assert fov["horizontal"]["real_deg"] == pytest.approx(44.27, abs=0.05)   # barrel distortion −0.7 %
    assert s["fields"][-1]["image_height_mm"] == pytest.approx(1.2, abs=1e-6)  # the sensor corner
    assert main(["lens", "info", "automotive.2.4mm", "--sensor-mm", "0", "1"]) == 2
