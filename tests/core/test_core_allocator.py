"""After `import workbench`, frame-sized arrays come from glibc's heap (freed memory is kept for
the next frame) instead of fresh mmaps; a user's own MALLOC_* settings are left alone."""
import os
import subprocess
import sys

import pytest

SCRIPT = r"""
import ctypes, sys
import numpy as np

class MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                               "fsmblks", "uordblks", "fordblks", "keepcost")]

libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = MallInfo2
import workbench
from workbench.allocator import tune_allocator
planes = [np.ones((480, 640, 3), np.float32) for _ in range(4)]     # 3.7 MB each
print(tune_allocator(), libc.mallinfo2().hblkhd)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
@pytest.mark.parametrize("user_setting", [False, True])
def test_frame_planes_come_from_the_heap_unless_the_user_set_the_allocator(user_setting):
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    if user_setting:
        env["MALLOC_MMAP_THRESHOLD_"] = "131072"
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    tuned, mmapped_bytes = done.stdout.split()
    if user_setting:
        assert tuned == "False" and int(mmapped_bytes) >= 4 * 480 * 640 * 3 * 4
    else:
        assert tuned == "True" and int(mmapped_bytes) < 480 * 640 * 3 * 4
