#!/usr/bin/env bash
# Renders one scene with kdtrace and Blender Cycles at equal spp and equal time and prints the
# table of docs/compare_cycles.md. Makes a Python 3.11 venv with numpy + bpy 5.0.1 outside the
# repository (~/.cache/kdtrace/venv-bpy, ~400 MB from PyPI, once; KDT_CYCLES_VENV overrides
# it) and builds kdtrace Release if needed. Arguments go to scripts/compare_cycles.py (--help).
set -euo pipefail
cd "$(dirname "$0")/.."

CACHE="${KDT_CACHE_DIR:-$HOME/.cache/kdtrace}"
VENV="${KDT_CYCLES_VENV:-$CACHE/venv-bpy}"
if ! "$VENV/bin/python" -c 'import bpy, numpy' 2>/dev/null; then
    PY="$(command -v python3.11 || true)"
    if [[ -z "$PY" ]]; then
        echo "compare_cycles: bpy 5.0.1 needs Python 3.11 (python3.11 not found)" >&2
        exit 1
    fi
    echo "compare_cycles: making $VENV (numpy, bpy==5.0.1)"
    "$PY" -m venv "$VENV"
    "$VENV/bin/pip" install --quiet --upgrade pip
    "$VENV/bin/pip" install --quiet numpy bpy==5.0.1
fi

if [[ ! -d build/release ]]; then
    cmake --preset release >/dev/null
fi
cmake --build build/release --target kdtrace -j2 >/dev/null

exec "$VENV/bin/python" scripts/compare_cycles.py "$@"
