#!/usr/bin/env bash
# The whole test suite: install, fetch the dragon, build Release and run every test, run the
# unit tests again under ASan+UBSan, fuzz every reader of untrusted files (about 120 s in
# all, see scripts/run_fuzz.sh), and check formatting.
# The ASan unit tests run last, so ctest's summary closes the output.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/fetch_assets.sh

echo "== clang-format"
bash scripts/check_format.sh

echo "== release build and tests"
cmake --preset release >/dev/null
cmake --build --preset release
ctest --preset release -j2

echo "== fuzzing the readers (PLY, OBJ, tree cache, images, scenes)"
bash scripts/run_fuzz.sh

echo "== asan+ubsan build and unit tests"
cmake --preset asan >/dev/null
cmake --build --preset asan
ASAN_OPTIONS=detect_leaks=1 ctest --preset asan -j2

