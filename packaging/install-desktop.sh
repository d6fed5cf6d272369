#!/usr/bin/env bash
# Register the workbench with the desktop (freedesktop conventions) for the current user:
# menu entry, icon, and the project file type (*.cwproj, application/x-camera-workbench-project).
#   bash packaging/install-desktop.sh            # install into ~/.local/share
#   bash packaging/install-desktop.sh --remove   # undo
# `workbench-gui` must be on PATH (pip install the wheel, or add .venv/bin to PATH).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
data="${XDG_DATA_HOME:-$HOME/.local/share}"
apps="$data/applications"; mime="$data/mime"; icons="$data/icons/hicolor/scalable/apps"
if [ "${1:-}" = "--remove" ]; then
  rm -f "$apps/camera-workbench.desktop" "$mime/packages/camera-workbench-mime.xml" "$icons/camera-workbench.svg"
else
  mkdir -p "$apps" "$mime/packages" "$icons"
  install -m 0644 "$here/desktop/camera-workbench.desktop" "$apps/"
  install -m 0644 "$here/desktop/camera-workbench-mime.xml" "$mime/packages/"
  install -m 0644 "$here/../resources/icons/camera-workbench.svg" "$icons/"
fi
command -v update-mime-database >/dev/null && update-mime-database "$mime" || true
command -v update-desktop-database >/dev/null && update-desktop-database "$apps" || true
command -v gtk-update-icon-cache >/dev/null && gtk-update-icon-cache -q -t "$data/icons/hicolor" || true
echo "desktop entry, icon and project file type ${1:+removed}${1:-installed} under $data"
