"""`workbench self-test`: a small end-to-end check that an installed or frozen workbench works.

It runs the paper camera's pipeline on a Macbeth chart at 64×48 and renders a 32×24 city frame
through the whole pipeline, checking that every stage gives finite, non-empty images; it prints
one line per check and exits 0 only if all pass. Used by the frozen app's --self-test.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def register(sub) -> None:
    p = sub.add_parser("self-test", help="run a 64×48 chart pipeline and a 32×24 city render; exit 0 if they work")
    p.add_argument("--no-city", action="store_true", help="skip the Mitsuba city render")
    p.set_defaults(func=cmd_self_test)


def _check_result(result) -> str:
    srgb = np.asarray(result.isp.srgb)
    if not np.all(np.isfinite(srgb)) or float(srgb.std()) <= 0.0:
        raise RuntimeError("the sRGB image is not finite or is uniform")
    return f"sRGB {srgb.shape[1]}x{srgb.shape[0]}, mean {srgb.mean():.3f}"


def _small(project, rows: int, cols: int):
    return project.updated(sensor=project.sensor.updated(rows=rows, cols=cols))


def cmd_self_test(args: argparse.Namespace) -> int:
    from workbench import __version__
    from workbench.pipeline import Pipeline
    from workbench.project import load_project
    from workbench.render.variants import select_variant

    from workbench.diagnostics import check_environment
    print(f"workbench {__version__} self-test")
    for comp in check_environment():
        print(f"  {'ok ' if comp.ok else 'no '} {comp.name}: {comp.detail}")
    t0 = time.perf_counter()
    chart = _small(load_project("paper_camera"), 48, 64)
    print(f"  chart pipeline: {_check_result(Pipeline(chart).run())} ({time.perf_counter() - t0:.1f} s)")
    if not args.no_city:
        t0 = time.perf_counter()
        city = _small(load_project("city_paper_camera"), 24, 32)
        city = city.updated(render=city.render.updated(spp=4))
        variant = select_variant()
        print(f"  city render ({variant}): {_check_result(Pipeline(city).run())} "
              f"({time.perf_counter() - t0:.1f} s)")
    print("self-test passed")
    return 0
