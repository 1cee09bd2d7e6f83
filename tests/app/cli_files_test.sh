#!/bin/bash
# File names and numbers on the command line, one CASE each (see the cases below).
# Usage: cli_files_test.sh CASE KDTRACE WORKDIR ASSETS. Prints "PASS: CASE" or "FAIL: why".
set -u
case_name=$1 kdt=$2 dir=$3 assets=$4
rm -rf "$dir" && mkdir -p "$dir" || exit 1
cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
export KDT_CACHE_DIR=$dir/cache
cp /usr/share/assimp/models/PLY/cube.ply cube.ply

# refused EXPECTED COMMAND...: the command must fail, its whole stderr being
# "kdtrace: error: EXPECTED" (so nothing, not even "loading", came before the error).
refused() {
    local expect=$1
    shift
    out=$("$kdt" "$@" 2>&1) && fail "accepted: $*"
    [[ $out == "kdtrace: error: $expect" ]] || fail "$*: expected '$expect', got: $out"
    echo "refused: $* -> $out"
}

case $case_name in
extensions)
    # An output written in one format refuses another extension; `scene -o -` writes the
    # JSON to stdout.
    refused "-o out.png: the scene is written as JSON (- for standard output); give a .json file name" \
        scene cube.ply -o out.png
    [[ -e out.png ]] && fail "scene -o out.png wrote a file"
    "$kdt" scene cube.ply -o OUT.JSON >/dev/null || fail "scene -o OUT.JSON refused"
    # -o -: the JSON alone on stdout, the summary on stderr, no file named '-'.
    "$kdt" scene cube.ply -o - >stdout.json 2>stderr.txt || fail "scene -o - failed"
    [[ -e - ]] && fail "scene -o - wrote a file named '-'"
    python3 -c 'import json, sys; json.load(open(sys.argv[1]))' stdout.json ||
        fail "scene -o -: stdout is not JSON: $(head -c 200 stdout.json)"
    grep -q '^scene cube.ply: 1 meshes' stderr.txt || fail "scene -o -: no summary: $(cat stderr.txt)"
    cmp -s stdout.json OUT.JSON || fail "scene -o - differs from scene -o OUT.JSON"
    ;;
bench_dirs)
    # Bench output directories and --save-views are checked before any work, with errors
    # naming the flag.
    refused "-o /proc/x: cannot create the directory: No such file or directory" \
        bench converge cube.ply --no-plot -o /proc/x
    touch file
    refused "-o file: exists and is not a directory" bench converge cube.ply --no-plot -o file
    refused "--make-binary /proc/zz: cannot create the directory: No such file or directory" \
        bench load cube.ply --no-assimp --make-binary /proc/zz
    # --save-views is checked before the model is loaded (no "loading" line before the error).
    refused "--save-views /proc/zz: cannot make the directory (No such file or directory)" \
        bench kdtree --model cube.ply --views "$assets/views/dragon.json" --repeat 1 \
        --save-views /proc/zz
    ;;
bench_ranges)
    # Ranges that --help states are the ones accepted.
    refused "--width must be in [1, 16384] (got 16385)" bench converge --width 16385
    "$kdt" bench converge --help | grep -q -- '--width INT:\[1, 16384\]' ||
        fail "bench converge --help does not state --width's bound"
    refused "--robust-rays must be in [1, 10000000] (got 10000001)" \
        bench kdtree --robust-rays 10000001
    ;;
numbers)
    # A number no double holds is out of range, not "not a number".
    refused "--exposure must be in [-64, 64] (got '1e-400', too close to 0 for a double)" \
        render --exposure 1e-400 -o x.png
    refused "--spp must be in (0, 1073741824] (got '1e400', too large for a double)" \
        render --spp 1e400 -o x.png
    refused "--spp must be a number (got '1e4x')" render --spp 1e4x -o x.png
    ;;
many_views)
    # 5000 views: the error names the first 20 and the count, not all of them.
    python3 - <<'EOF' || fail "cannot write many.json"
import json
views = [{"name": "v%d" % i, "eye": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0],
          "vfov_degrees": 40} for i in range(5000)]
json.dump({"width": 8, "height": 8, "views": views}, open("many.json", "w"))
EOF
    out=$("$kdt" render cube.ply --views many.json --view nope -o x.png 2>&1) &&
        fail "--view nope accepted"
    echo "$out"
    (( ${#out} < 400 )) || fail "a ${#out}-byte error"
    [[ $out == *'no view named "nope" (views: v0, v1, '*', v19, ... (5000 views))' ]] ||
        fail "views list: $out"
    ;;
*)
    fail "unknown case $case_name"
    ;;
esac
echo "PASS: $case_name"
