"""Preview PNGs are written whole or not at all (previews.save_png / save_image): a writer that
fails half-way leaves the previous file byte for byte and no temporary beside it."""
import numpy as np
import pytest
from PIL import Image

from workbench.previews import save_image, save_png


def test_png_round_trips_and_a_failed_save_keeps_the_old_file(tmp_path, monkeypatch):
    target = tmp_path / "srgb.png"
    ramp = np.linspace(0.0, 1.0, 12 * 8).reshape(8, 12)
    save_png(target, ramp)
    assert np.array_equal(np.asarray(Image.open(target)), np.round(ramp * 255).astype(np.uint8))
    before = target.read_bytes()

    import workbench.files as files

    def dies_half_way(fd, data):
        import os
        os.write(fd, data[: len(data) // 2])
        raise KeyboardInterrupt("killed")
    monkeypatch.setattr(files, "_write_all", dies_half_way)
    with pytest.raises(KeyboardInterrupt):
        save_image(target, Image.new("RGB", (5, 5), (255, 0, 0)))
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["srgb.png"]
