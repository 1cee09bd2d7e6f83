#!/usr/bin/env bash
# Runs every unit test executable (the threaded parts among them: OpenMP render passes,
# parallel SAH builds, batch queries, PLY reading on two threads, the viewer's threads) under
# ThreadSanitizer, one log per executable. Uses the `tsan` preset: clang with LLVM's libomp and
# its Archer tool, which tells TSan about OpenMP's barriers and reductions (GCC's libgomp is not
# instrumented, so a GCC TSan build reports every parallel region).
# tests/tsan/suppressions.txt hides libomp's own internals only. `ctest --preset tsan` sets the
# same environment. Exits non-zero on any report or failed test. Not part of scripts/test.sh
# (about 5 min).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
archer=/usr/lib/llvm-14/lib/libarcher.so
[ -f "$archer" ] || { echo "run_tsan: $archer missing (Debian libomp-14-dev)" >&2; exit 1; }

cmake --preset tsan >/dev/null
cmake --build --preset tsan --target kdt_unit_tests
# Every unit test executable (one per renderer module, and the viewer's headless ones).
targets=()
for exe in "$root"/build/tsan/tests/kdt_*_tests; do targets+=("$(basename "$exe")"); done

status=0
for t in "${targets[@]}"; do
    log="$root/build/tsan/$t.tsan.log"
    set +e
    OMP_TOOL_LIBRARIES="$archer" \
    TSAN_OPTIONS="suppressions=$root/tests/tsan/suppressions.txt:halt_on_error=0:exitcode=66" \
        "$root/build/tsan/tests/$t" >"$log" 2>&1
    rc=$?
    set -e
    reports=$(grep -c "WARNING: ThreadSanitizer" "$log" || true)
    echo "run_tsan: $t: exit $rc, $reports reports ($log)"
    if [ "$rc" -ne 0 ] || [ "$reports" -ne 0 ]; then status=1; fi
done
[ "$status" -eq 0 ] && echo "run_tsan: OK, no ThreadSanitizer report" || echo "run_tsan: FAILED"
exit "$status"
