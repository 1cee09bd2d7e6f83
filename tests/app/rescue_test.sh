#!/bin/bash
# An image that cannot be written at the end of a render is saved to $TMPDIR instead, and the
# error names that file: the output directory is removed while the render runs (after the
# check before rendering), then SIGINT ends the render. Usage: rescue_test.sh KDTRACE WORKDIR.
set -u
kdt=$1 dir=$2
rm -rf "$dir" && mkdir -p "$dir/out" "$dir/tmp" || exit 1
fail() { echo "FAIL: $*"; cat "$dir/log" 2>/dev/null; exit 1; }
# Without job control bash starts a background job with SIGINT ignored: env restores it.
TMPDIR=$dir/tmp env --default-signal=INT "$kdt" render /usr/share/assimp/models/PLY/cube.ply \
    --time 60 --width 64 --height 48 --threads 1 --cache-dir "$dir/cache" \
    -o "$dir/out/x.pfm" >"$dir/log" 2>&1 &
pid=$!
# The cache line is printed after the output check, before the first pass.
for _ in $(seq 600); do
    grep -q "kd-tree cache" "$dir/log" && break
    kill -0 $pid 2>/dev/null || fail "kdtrace ended before rendering"
    sleep 0.1
done
rm -rf "$dir/out"
kill -s INT $pid
wait $pid
rc=$?
[ $rc -eq 1 ] || fail "exit status $rc, expected 1"
rescued="$dir/tmp/kdtrace-rescued-$pid-x.pfm"
grep -q "x.pfm: .*; the image was saved to $rescued instead" "$dir/log" ||
    fail "the error does not name $rescued"
"$kdt" info "$rescued" | grep -q "size: *64x48" || fail "$rescued is not the image"
[ -z "$(find "$dir" -name '*.tmp*')" ] || fail "temporary files left"
echo "PASS: rescue"
