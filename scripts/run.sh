#!/usr/bin/env bash
# The main job: install, build Release, and render the built-in default scene headless
# into out/default.png (no download needed). Extra arguments go to `kdtrace render`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release
mkdir -p out
./build/release/bin/kdtrace render --spp 64 -o out/default.png "$@"
echo "run: wrote out/default.png"
