"""Where and how precisely a detector runs: torch threads, CPU or CUDA, and bf16 autocast.

Precision ('auto' | 'fp32' | 'bf16' | 'bf16_native'): 'auto' = bf16 autocast on a CUDA GPU that
supports bf16 (Ampere and later), float32 elsewhere; 'bf16_native' = the same, and bf16 also on a
CPU that computes it in hardware (AVX-512 BF16 or AMX: about half resnet18's float32 step there),
never on one that emulates it (10–12x slower on an AVX2 EPYC, bench detect); 'bf16' asks for it on
any device (on the CPU it runs the same mixed-precision path, which is how it is tested without a
GPU); 'fp32' never. Losses and decoding are always float32. bf16 has float32's exponent range, so
no loss scaling is needed; float16 (which would need it) is not used.
"""
from __future__ import annotations

import os
from pathlib import Path

from workbench.compute.local import THREAD_BUDGET_ENV
from workbench.errors import ParameterError

PRECISIONS = ("auto", "fp32", "bf16", "bf16_native")
NATIVE_BF16_CPU_FLAGS = ("avx512_bf16", "amx_bf16")   # /proc/cpuinfo flags of CPUs that compute bf16


def choose_threads(requested: int | None = None, concurrent_processes: int = 1) -> int:
    """Torch threads for one process: `requested`, else the thread budget the compute backend gave
    this worker, else half the usable cores shared among concurrent_processes (at least 1), so
    that two CPU-bound processes never oversubscribe."""
    if requested is not None:
        if requested < 1:
            raise ParameterError("threads", requested, "an integer ≥ 1 (or None: half the cores)")
        return int(requested)
    budget = os.environ.get(THREAD_BUDGET_ENV, "")
    if budget.isdigit() and int(budget) > 0:
        return int(budget)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, cores // (2 * max(1, concurrent_processes)))


def pick_device(device: str) -> str:
    """'cuda' or 'cpu' for 'auto' | 'cuda' | 'cpu' (asking for 'cuda' without a GPU is an error)."""
    import torch
    if device not in ("auto", "cuda", "cpu"):
        raise ParameterError("device", device, "one of 'auto', 'cuda', 'cpu'")
    if device == "cuda" and not torch.cuda.is_available():
        raise ParameterError("device", device, "'cpu' or 'auto': torch sees no CUDA GPU here")
    return "cuda" if device in ("auto", "cuda") and torch.cuda.is_available() else "cpu"


def cpu_has_native_bf16(cpuinfo: str | None = None) -> bool:
    """Whether this CPU computes bf16 in hardware (AVX-512 BF16 or AMX): without it torch emulates
    bf16 and autocast makes a CPU training step 10–12x slower (bench detect on an AVX2 EPYC)."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text(errors="replace")
        except OSError:
            return False
    flags = {flag for line in cpuinfo.splitlines() if line.startswith("flags")
             for flag in line.split(":", 1)[-1].split()}
    return any(flag in flags for flag in NATIVE_BF16_CPU_FLAGS)


def autocast_dtype(device: str, precision: str):
    """torch.bfloat16 when a run on `device` ('cpu' | 'cuda') should use bf16 autocast, else None.
    'auto': bf16 on a bf16-capable CUDA GPU only; 'bf16_native': also on a CPU that computes bf16
    in hardware (cpu_has_native_bf16), float32 elsewhere."""
    import torch
    if precision not in PRECISIONS:
        raise ParameterError("precision", precision, "one of " + ", ".join(map(repr, PRECISIONS)))
    if precision == "bf16":
        return torch.bfloat16
    if precision in ("auto", "bf16_native") and device == "cuda" and torch.cuda.is_bf16_supported():
        return torch.bfloat16
    if precision == "bf16_native" and device == "cpu" and cpu_has_native_bf16():
        return torch.bfloat16
    return None


def autocast(device: str, dtype):
    """The autocast context for a run (a no-op one when dtype is None)."""
    import torch
    return torch.autocast(device_type=device, dtype=dtype or torch.bfloat16, enabled=dtype is not None)


def prepare_model(model, device: str):
    """The model on `device`, in channels-last memory order (oneDNN's fast path for convolutions
    on the CPU: 20 % less time per training image for 'mobile', bench detect)."""
    import torch
    return model.to(device).to(memory_format=torch.channels_last)


def prepare_input(x, device: str):
    """A batch on `device` in the model's memory order (prepare_model)."""
    import torch
    return x.to(device, non_blocking=True).contiguous(memory_format=torch.channels_last)


def compute_unit(device: str) -> str:
    """What a run computes on, in words: the GPU's name on 'cuda', else the CPU's model."""
    if device == "cuda":
        import torch
        return torch.cuda.get_device_name()
    return cpu_model()


def cpu_model(cpuinfo: str | None = None) -> str:
    """The CPU's model name as /proc/cpuinfo gives it ('unknown' where it cannot be read)."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text(errors="replace")
        except OSError:
            return "unknown"
    return next((line.split(":", 1)[1].strip() for line in cpuinfo.splitlines() if line.startswith("model name")),
                "unknown")
