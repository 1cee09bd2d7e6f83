#!/usr/bin/env bash
# Renders the comparison scenes with kdtrace and Mitsuba 3 and prints the Markdown tables
# (docs/compare_mitsuba.md). Makes a Python venv with numpy + mitsuba outside the repository
# (~/.cache/kdtrace/venv-mitsuba, ~100 MB from PyPI, once) and builds kdtrace Release if
# needed. Arguments go to scripts/compare_mitsuba.py (--help lists them).
set -euo pipefail
cd "$(dirname "$0")/.."

CACHE="${KDT_CACHE_DIR:-$HOME/.cache/kdtrace}"
VENV="${KDT_MITSUBA_VENV:-$CACHE/venv-mitsuba}"
if ! "$VENV/bin/python" -c 'import mitsuba, numpy' 2>/dev/null; then
    echo "compare_mitsuba: making $VENV (numpy, mitsuba)"
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet --upgrade pip
    "$VENV/bin/pip" install --quiet numpy 'mitsuba>=3.5,<4'
fi

if [[ ! -d build/release ]]; then
    cmake --preset release >/dev/null
fi
cmake --build build/release --target kdtrace -j2 >/dev/null

exec "$VENV/bin/python" scripts/compare_mitsuba.py "$@"
