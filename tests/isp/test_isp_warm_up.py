"""warm_up_pixel_kernels loads every compiled signal, sensor and ISP kernel with the argument types
a full frame uses: in a fresh process, after the warm-up, full 640×480 frames through every
illuminant correction, highlight mode, normalisation and compiled demosaic compile or load
nothing more."""
import subprocess
import sys

SCRIPT = r"""
import numpy as np
from workbench.project import load_project
from workbench.warm_up import warm_up_pixel_kernels
from workbench.isp import kernels, sensor_image_to_srgb
from workbench.sensor import kernels as sensor_kernels, irradiance_to_signal_rate, resolve_exposure, signal_rate_to_sensor_image
from workbench.stages.geometry import project_geometry
from workbench.stages.optics import form_optical_image
from workbench.stages.scene import chart_scene

KERNELS = [kernels.colour_pixels, kernels.demosaic_2x2, kernels.ics_maxima, kernels.bright_sums,
           kernels.srgb_encode_flat, kernels.sample_ics, kernels.grey_pixel_sums, sensor_kernels.read_out_block,
           sensor_kernels.project_by_tile, kernels.normalise_raw, sensor_kernels.scale_rates,
           sensor_kernels.mean_f64]
project = load_project("paper_camera")
warm_up_pixel_kernels(project)
warm = [len(k.signatures) for k in KERNELS]
assert all(n == 1 for n in warm), warm
geometry = project_geometry(project)
oi = form_optical_image(chart_scene(project.scene, geometry), project.optics, geometry, None)
rate = irradiance_to_signal_rate(oi, project.sensor)
image = signal_rate_to_sensor_image(rate, project.sensor, resolve_exposure(rate, project.sensor),
                                    np.random.default_rng(1), wavelengths_nm=oi.wavelengths_nm)
assert image.dn.shape == (480, 640)
for method in ("none", "gray_world", "gray_pixels", "white_world", "manual"):
    for highlights in ("neutral", "clip"):
        for normalize in ("swing", "max"):
            for demosaic in ("bilinear", "malvar2004"):
                sensor_image_to_srgb(image, project.isp.updated(illuminant_correction=method, highlights=highlights,
                                                                normalize=normalize, demosaic=demosaic))
after = [len(k.signatures) for k in KERNELS]
assert after == warm, (warm, after)
print("ok")
"""


def test_the_warm_up_loads_every_kernel_a_full_frame_calls():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and done.stdout.strip().endswith("ok"), done.stderr[-2000:]
