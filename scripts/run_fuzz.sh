#!/usr/bin/env bash
# Fuzzes the PLY reader with libFuzzer under ASan+UBSan for ${KDT_FUZZ_SECONDS:-60} s on a
# copy of the seed corpus (tests/fuzz/corpus). Configures and builds the `fuzz` preset
# (clang) unless --no-build is given with KDT_FUZZER pointing at a built fuzzer.
# Exits non-zero on any crash, leak, timeout or sanitizer report.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${KDT_FUZZ_SECONDS:-60}"

if [ "${1:-}" != "--no-build" ]; then
    cmake --preset fuzz -S "$root" >/dev/null
    cmake --build "$root/build/fuzz" --target ply_fuzzer -j2
    fuzzer="$root/build/fuzz/tests/ply_fuzzer"
else
    fuzzer="${KDT_FUZZER:?KDT_FUZZER must name the fuzzer with --no-build}"
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/corpus" "$work/artifacts"
cp "$root"/tests/fuzz/corpus/* "$work/corpus/"

echo "run_fuzz: $fuzzer for $seconds s on $(ls "$work/corpus" | wc -l) seeds"
set +e
ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:symbolize=1" \
UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
"$fuzzer" "$work/corpus" -dict="$root/tests/fuzz/ply.dict" -max_total_time="$seconds" \
    -timeout=10 -rss_limit_mb=2048 -max_len=8192 -print_final_stats=1 \
    -artifact_prefix="$work/artifacts/" 2>"$work/log"
status=$?
set -e
tail -n 25 "$work/log"
if [ $status -ne 0 ] || ls "$work/artifacts"/* >/dev/null 2>&1 ||
   grep -qE "ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error:" "$work/log"; then
    mkdir -p "$root/build/fuzz-artifacts"
    cp "$work"/artifacts/* "$root/build/fuzz-artifacts/" 2>/dev/null || true
    echo "run_fuzz: FAILED (exit $status); reproducers in $root/build/fuzz-artifacts" >&2
    exit 1
fi
echo "run_fuzz: OK, no crash, leak or sanitizer report in $seconds s"
