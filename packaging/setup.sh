#!/usr/bin/env bash
# Set up the workbench on a fresh Debian 12 / Python 3.11 machine, then run a job.
#   bash packaging/setup.sh demo   # set up, then open the window on the paper's sample (with a
#                                  # display) or run the headless demo (without one)
#   bash packaging/setup.sh test   # set up, then run the full test suite (2 workers;
#                                  # WORKBENCH_TEST_WORKERS=0 runs it in one process)
#   bash packaging/setup.sh        # set up only
# Idempotent: a second run reuses .venv and skips what is installed.
set -euo pipefail
cd "$(dirname "$0")/.."
job="${1:-none}"; shift || true
PY="${PYTHON:-python3.11}"
command -v "$PY" >/dev/null || PY=python3

# Debian packages: a recent LLVM for Mitsuba's llvm variants, Xvfb + xcb libs for GUI tests.
apt_pkgs=(libllvm19 xvfb desktop-file-utils shared-mime-info libxcb-icccm4 libxcb-keysyms1 libxcb-image0 libxcb-render-util0 libxkbcommon-x11-0 libxcb-xinerama0 libxcb-randr0 libxcb-shape0 libxcb-cursor0 libgl1 libegl1 libosmesa6)
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  missing=()
  for p in "${apt_pkgs[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
  if [ ${#missing[@]} -gt 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  fi
fi

if [ ! -x .venv/bin/python ]; then "$PY" -m venv .venv; fi
VPY=.venv/bin/python
stamp=.venv/.installed-$(cat pyproject.toml packaging/setup.sh | sha1sum | cut -c1-12)
if [ ! -f "$stamp" ]; then
  "$VPY" -m pip install -q --upgrade pip
  # torch first and pinned: an unpinned torch drags in several GB of CUDA packages.
  # --no-compile: Python compiles only the modules it imports, when it first imports them (byte-
  # compiling every installed file took about two thirds of torch's install time)
  "$VPY" -m pip install -q --no-compile "torch==2.13.0"
  "$VPY" -m pip install -q --no-compile -e ".[gui,detect,cluster,test]"
  rm -f .venv/.installed-*; touch "$stamp"
fi

case "$job" in
  demo)
    # The window on the paper's sample project where there is a display; the headless demo where
    # there is none (CI, ssh): both say which one runs.
    if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ] && [ -z "${WORKBENCH_HEADLESS:-}" ]; then
      echo "setup.sh demo: a display is present: opening the window on paper_camera (WORKBENCH_HEADLESS=1 for the headless demo)" >&2
      exec .venv/bin/workbench gui paper_camera
    fi
    echo "setup.sh demo: no display: running the headless demo into ${1:-demo-output}/" >&2
    exec .venv/bin/workbench demo --out "${1:-demo-output}" ;;
  # the suite on 2 pytest-xdist workers, a test file per worker at a time (one Ray cluster, one Xvfb,
  # one Qt application per file); each worker gets cores/2 threads (tests/conftest.py)
  # Python may cache what it compiles: the set-up installs without byte-compiling, and where the
  # environment sets PYTHONDONTWRITEBYTECODE every test subprocess (CLI runs, pool and Ray workers)
  # would compile torch, Ray and the rest from source again (it doubled those tests' time)
  test) unset PYTHONDONTWRITEBYTECODE
        exec .venv/bin/python -m pytest -n "${WORKBENCH_TEST_WORKERS:-2}" --dist loadfile "$@" ;;
  none) ;;
  *) echo "unknown job '$job' (use: demo | test)" >&2; exit 2 ;;
esac
