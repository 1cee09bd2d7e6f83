#!/usr/bin/env bash
# The main job: install, build Release, and show the built-in default scene (no download
# needed): in the viewer when a display is present, else rendered headless into
# out/default.png. Extra arguments go to `kdtrace view` or `kdtrace render`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release
kdtrace=./build/release/bin/kdtrace
# With a display (and the viewer built), the viewer; else a headless render.
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ] && "$kdtrace" view --help >/dev/null 2>&1; then
    exec "$kdtrace" view "$@"
fi
mkdir -p out
"$kdtrace" render --spp 64 -o out/default.png "$@"
echo "run: wrote out/default.png"
