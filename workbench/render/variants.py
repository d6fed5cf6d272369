"""Choose and import a spectral Mitsuba 3 variant (GPU → CPU JIT → scalar), LLVM path set first.

Dr.Jit's LLVM backend must be pointed at LLVM 19 *before* mitsuba is imported: the system's
default libLLVM 15 crashes the JIT ("Cannot select fmaximum"), and automatic detection can
pick the wrong library (mitsuba3 #451)."""
from __future__ import annotations

import glob
import logging
import os
import subprocess
import sys

from workbench.errors import InvalidValueError
from workbench.compute.local import THREAD_BUDGET_ENV

log = logging.getLogger(__name__)

SPECTRAL_VARIANTS = ("cuda_ad_spectral", "llvm_ad_spectral", "scalar_spectral")
_BACKEND_OF = {"cuda_ad_spectral": "cuda", "llvm_ad_spectral": "llvm", "scalar_spectral": None}
_LLVM_CANDIDATES = ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
                    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
                    "/usr/lib/llvm-19/lib/libLLVM.so.19.1",
                    "/usr/lib/llvm-19/lib/libLLVM-19.so")


def find_libllvm() -> str | None:
    """Path of an LLVM 19 shared library (from `dpkg -L libllvm19`, then the usual paths)."""
    try:
        listing = subprocess.run(["dpkg", "-L", "libllvm19"], capture_output=True, text=True,
                                 timeout=10, check=False).stdout.split()
    except (OSError, subprocess.SubprocessError):
        listing = []
    found = [p for p in listing if "libLLVM" in os.path.basename(p) and ".so" in p]
    found += list(_LLVM_CANDIDATES) + sorted(glob.glob("/usr/lib/*/libLLVM*19*.so*"))
    for path in found:
        if os.path.isfile(path):
            return path
    return None


def _set_llvm_path() -> None:
    """Set DRJIT_LIBLLVM_PATH unless the user already did (only effective before import)."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return
    path = find_libllvm()
    if path is None:
        log.warning("no libLLVM 19 found; the LLVM variant may be unavailable or crash")
        return
    if "drjit" in sys.modules:
        log.warning("drjit was imported before DRJIT_LIBLLVM_PATH could be set to %s", path)
        return
    os.environ["DRJIT_LIBLLVM_PATH"] = path


def choose_variant(compiled: list[str], backends: dict[str, bool], prefer: str | None = None,
                   strict: bool = False) -> tuple[str, list[str]]:
    """Pure choice: the first usable variant of [prefer, cuda, llvm, scalar] and why others failed.

    compiled: variants the mitsuba build has; backends: {'cuda': bool, 'llvm': bool} availability.
    strict: `prefer` is pinned (a project's render.variant: bitwise reproducibility is promised for
    it), so it is that variant or a ParameterError saying why not, never another one.
    Returns (variant, reasons-for-skipping). Raises ValueError for an unknown `prefer` or when
    no spectral variant is usable."""
    if prefer is not None and prefer not in SPECTRAL_VARIANTS:
        raise InvalidValueError(f"render variant '{prefer}' is not allowed; allowed: "
                         f"{', '.join(SPECTRAL_VARIANTS)} (or None for automatic)")
    order = ([prefer] if prefer else []) + [v for v in SPECTRAL_VARIANTS if v != prefer]
    skipped = []
    for variant in order:
        backend = _BACKEND_OF[variant]
        if variant not in compiled:
            skipped.append(f"{variant}: not compiled into this mitsuba build")
        elif backend is not None and not backends.get(backend, False):
            skipped.append(f"{variant}: the {backend} backend is not available on this machine")
        else:
            return variant, skipped
        if strict and variant == prefer:
            raise _pinned_refusal(prefer, skipped[-1])
    raise InvalidValueError("no spectral Mitsuba variant is usable: " + "; ".join(skipped))


def _pinned_refusal(variant: str, why: str):
    from workbench.errors import ParameterError
    return ParameterError("render.variant", variant, f"a variant this machine can run ({why}); set it to null "
                          "to choose the best available one (results are then bitwise the same only on "
                          "machines that choose the same)")


def select_variant(prefer: str | None = None, strict: bool = False) -> str:
    """Set the best usable spectral variant (trying `prefer` first) and return its name.

    Order: cuda_ad_spectral → llvm_ad_spectral → scalar_spectral; each skip is logged. strict: a
    pinned `prefer` that cannot load is a ParameterError (choose_variant), not a fallback."""
    _set_llvm_path()
    import drjit as dr
    import mitsuba as mi

    backends = {"cuda": bool(dr.has_backend(dr.JitBackend.CUDA)),
                "llvm": bool(dr.has_backend(dr.JitBackend.LLVM))}
    compiled = list(mi.variants())
    while True:
        variant, skipped = choose_variant(compiled, backends, prefer, strict)
        for reason in skipped:
            log.info("render variant skipped: %s", reason)
        try:
            if mi.variant() != variant:
                mi.set_variant(variant)
            break
        except (ImportError, RuntimeError) as exc:   # e.g. a GPU whose driver/OptiX fails to start
            if strict and variant == prefer:
                raise _pinned_refusal(prefer, f"it failed to load: {type(exc).__name__}") from None
            log.warning("render variant %s failed to load (%s); trying the next one", variant, exc)
            compiled.remove(variant)
    allowed = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    budget = os.environ.get(THREAD_BUDGET_ENV, "")
    if variant != "scalar_spectral" and budget.isdigit() and int(budget) > 0:
        dr.set_thread_count(min(int(budget), allowed or int(budget)))   # a worker's thread budget
    elif variant != "scalar_spectral" and allowed and allowed < (os.cpu_count() or allowed):
        dr.set_thread_count(allowed)     # restricted affinity: Embree can crash otherwise (#716)
    log.info("render variant: %s", variant)
    return variant


def import_mitsuba(prefer: str | None = None):
    """The mitsuba module with a spectral variant set (see select_variant)."""
    select_variant(prefer)
    import mitsuba as mi

    return mi
