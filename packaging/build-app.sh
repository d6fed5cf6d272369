#!/usr/bin/env bash
# Build the one-folder frozen app into dist/camera-workbench/ and run its self-test.
#   bash packaging/build-app.sh        (after `bash packaging/setup.sh`; takes several minutes)
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/python ] || bash packaging/setup.sh
.venv/bin/python -m pip install -q -e ".[bundle]"
start=$(date +%s)
.venv/bin/pyinstaller --noconfirm --clean --log-level WARN --distpath dist --workpath build/pyinstaller \
  packaging/camera-workbench.spec
echo "built in $(( $(date +%s) - start )) s; bundle size: $(du -sh dist/camera-workbench | cut -f1)"
WORKBENCH_LOG_DIR="$(mktemp -d)" dist/camera-workbench/camera-workbench --self-test
