"""What this machine gives the workbench, and what to install when something is missing.

check_environment() lists each optional back-end (Mitsuba's LLVM variant, a CUDA GPU, an OpenGL
context for the 3-D view, torch for detectors) with whether it is usable and, if not, what to do.
The self-test prints it; the window shows the missing ones at start-up.
"""
from __future__ import annotations

import importlib.util
import os
from dataclasses import dataclass


@dataclass(frozen=True)
class Component:
    name: str
    ok: bool
    detail: str          # what was found, or what to install / set


def _llvm() -> Component:
    from workbench.render.variants import find_libllvm
    path = os.environ.get("DRJIT_LIBLLVM_PATH") or find_libllvm()
    if path and os.path.isfile(path):
        return Component("LLVM 19 (Mitsuba's fast CPU renderer)", True, path)
    return Component("LLVM 19 (Mitsuba's fast CPU renderer)", False,
                     "not found: renders fall back to the slow scalar variant. Install Debian's "
                     "libllvm19 (apt-get install libllvm19) or set DRJIT_LIBLLVM_PATH to a libLLVM 19")


def _cuda() -> Component:
    import ctypes.util
    if ctypes.util.find_library("cuda") or os.path.exists("/usr/lib/x86_64-linux-gnu/libcuda.so.1"):
        return Component("NVIDIA GPU (cuda_ad_spectral, torch CUDA)", True, "driver library found")
    return Component("NVIDIA GPU (cuda_ad_spectral, torch CUDA)", False,
                     "no CUDA driver: rendering and training run on the CPU (optional)")


def _opengl() -> Component:
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return Component("OpenGL display (3-D city view)", False,
                         "no display: the window needs an X11/Wayland session (or Xvfb: apt-get "
                         "install xvfb libxcb-icccm4 libxcb-keysyms1); headless commands still work")
    import ctypes.util
    if ctypes.util.find_library("GL") or ctypes.util.find_library("OpenGL"):
        return Component("OpenGL display (3-D city view)", True, "display and libGL found")
    return Component("OpenGL display (3-D city view)", False,
                     "libGL not found: install Mesa (apt-get install libgl1 libegl1 libgl1-mesa-dri)")


def _torch() -> Component:
    if importlib.util.find_spec("torch") is None:
        return Component("torch (detectors)", False,
                         "not installed: pip install torch==2.13.0 (CPU) before the [detect] extra")
    return Component("torch (detectors)", True, "installed")


def check_environment() -> list[Component]:
    """Each optional back-end with whether it is usable here and, if not, what to do."""
    return [_llvm(), _cuda(), _opengl(), _torch()]
