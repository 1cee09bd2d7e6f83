#!/usr/bin/env bash
# Fails when any of our C++ files differs from what clang-format makes of it.
set -euo pipefail
cd "$(dirname "$0")/.."
files=$(git ls-files '*.h' '*.cpp')
[ -z "$files" ] && exit 0
bad=0
for f in $files; do
    if ! clang-format --style=file "$f" | cmp -s - "$f"; then
        echo "needs clang-format: $f"
        bad=1
    fi
done
[ "$bad" = 0 ] && echo "format: ok"
exit $bad
