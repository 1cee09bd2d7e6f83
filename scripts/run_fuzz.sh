#!/usr/bin/env bash
# Fuzzes the readers of untrusted files with libFuzzer under ASan+UBSan, each target on a
# copy of its seed corpus (tests/fuzz/corpus/<target>) for its share of CI's budget (below,
# 125 s in all), or for KDT_FUZZ_SECONDS each when that is set. The ply target takes plain
# and gzip PLY in its one budget (see tests/fuzz/ply_fuzzer.cpp).
#   scripts/run_fuzz.sh [target...]        configures and builds the `fuzz` preset (clang)
#                                          and runs the targets given, default all
#   scripts/run_fuzz.sh --no-build target  runs the fuzzer KDT_FUZZER names (ctest does this)
# Exits non-zero on any crash, leak, timeout or sanitizer report; reproducers are copied to
# build/fuzz-artifacts/<target>.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
targets_all=(ply obj cache image scene)

budget() {
    case "$1" in
        ply) echo 40 ;;
        cache) echo 30 ;;
        image) echo 25 ;;
        obj | scene) echo 15 ;;
        *) echo "run_fuzz: unknown target '$1' (one of: ${targets_all[*]})" >&2; exit 2 ;;
    esac
}

# Options per target: a dictionary when there is one, and the longest input worth trying.
extra_args() {
    local dict="$root/tests/fuzz/$1.dict"
    [ -f "$dict" ] && echo "-dict=$dict"
    case "$1" in
        image) echo "-max_len=16384" ;;
        *) echo "-max_len=8192" ;;
    esac
}

# run_one <target> <fuzzer binary>
run_one() {
    local target="$1" fuzzer="$2"
    local seconds="${KDT_FUZZ_SECONDS:-$(budget "$target")}"
    local work
    work="$(mktemp -d)"
    mkdir -p "$work/corpus" "$work/artifacts"
    cp "$root/tests/fuzz/corpus/$target"/* "$work/corpus/"
    echo "run_fuzz: $target: $fuzzer for $seconds s on $(ls "$work/corpus" | wc -l) seeds"
    local status
    set +e
    # shellcheck disable=SC2046  # extra_args is a list of words
    ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:symbolize=1" \
    UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    "$fuzzer" "$work/corpus" $(extra_args "$target") -max_total_time="$seconds" \
        -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
        -artifact_prefix="$work/artifacts/" 2>"$work/log"
    status=$?
    set -e
    tail -n 25 "$work/log"
    # libFuzzer's timeout is wall-clock time: on a shared machine a stalled process can
    # trip it. A real hang hangs again, so a timeout input that now runs in time is not one.
    # Slow units (over 10 s, -report_slow_units) are reported, not failures: same reason.
    rm -f "$work"/artifacts/slow-unit-*
    local t
    for t in "$work"/artifacts/timeout-*; do
        [ -e "$t" ] || continue
        if "$fuzzer" -timeout=10 "$t" >>"$work/rerun.log" 2>&1; then
            echo "run_fuzz: $target: $(basename "$t") runs in time when re-run:" \
                 "the machine stalled, not the reader"
            rm "$t"
            grep -q "ERROR: libFuzzer: timeout" "$work/log" && status=0 &&
                sed -i 's/ERROR: libFuzzer: timeout/(stall, re-run in time)/' "$work/log"
        fi
    done
    if [ $status -ne 0 ] || ls "$work/artifacts"/* >/dev/null 2>&1 ||
       grep -qE "ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error:" "$work/log"; then
        mkdir -p "$root/build/fuzz-artifacts/$target"
        cp "$work"/artifacts/* "$root/build/fuzz-artifacts/$target/" 2>/dev/null || true
        rm -rf "$work"
        echo "run_fuzz: $target FAILED (exit $status); reproducers in" \
             "$root/build/fuzz-artifacts/$target" >&2
        return 1
    fi
    rm -rf "$work"
    echo "run_fuzz: $target OK, no crash, leak or sanitizer report in $seconds s"
}

if [ "${1:-}" = "--no-build" ]; then
    [ $# -eq 2 ] || { echo "usage: run_fuzz.sh --no-build <target>" >&2; exit 2; }
    budget "$2" >/dev/null
    run_one "$2" "${KDT_FUZZER:?KDT_FUZZER must name the fuzzer with --no-build}"
    exit
fi

targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${targets_all[@]}")
for t in "${targets[@]}"; do budget "$t" >/dev/null; done
cmake --preset fuzz -S "$root" >/dev/null
cmake --build "$root/build/fuzz" -j2 --target $(printf '%s_fuzzer ' "${targets[@]}")
failed=0
for t in "${targets[@]}"; do
    run_one "$t" "$root/build/fuzz/tests/${t}_fuzzer" || failed=1
done
exit $failed
