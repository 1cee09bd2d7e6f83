#!/bin/bash
# Smoke runs of `kdtrace bench kdtree` and `bench converge` on hostile input: degenerate
# models, output names a shell would misread. Tiny models and views,
# one repeat: no case depends on a time.
# Usage: bench_test.sh CASE KDTRACE WORKDIR. Prints "PASS: CASE" or "FAIL: reason".
set -u
case_name=$1 kdt=$2 dir=$3
rm -rf "$dir" && mkdir -p "$dir" || exit 1
cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
export KDT_CACHE_DIR=$dir/cache

# ply NAME VERTICES FACES: an ASCII PLY of the vertex lines ("x y z") and triangles ("a b c").
ply() {
    local name=$1 v=$2 f=$3
    {
        printf 'ply\nformat ascii 1.0\nelement vertex %d\n' "$(grep -c . <<<"$v")"
        printf 'property float x\nproperty float y\nproperty float z\n'
        printf 'element face %d\nproperty list uchar int vertex_indices\nend_header\n' \
            "$(grep -c . <<<"$f")"
        printf '%s\n' "$v"
        sed 's/^/3 /' <<<"$f"
    } >"$name"
}
# One 16x12 view at one sample per pixel, looking at the origin's neighbourhood.
cat >views.json <<'EOF'
{"width": 16, "height": 12, "samples_per_pixel": 1, "seed": 1,
 "views": [{"name": "A", "eye": [0, 0.12, 0.4], "target": [0, 0.12, 0], "up": [0, 1, 0],
            "vfov_degrees": 30}]}
EOF
kdtree=(bench kdtree --views views.json --repeat 1 --threads 1 --robust-rays 100)

case $case_name in
kdtree_no_rays)
    # 50 triangles at one point, and one triangle on a line: no diffuse ray leaves them and
    # no ray can be aimed at a closed fan. Every mean, share or ratio of no rays is "-", in
    # the Markdown and the CSV alike; none is nan. One row (sah), so that it is the "best tree"
    # of the Embree table whatever the timing.
    ply point.ply "$(printf '0 0.1 0\n0 0.1 0\n0 0.1 0')" "$(for i in $(seq 50); do echo 0 1 2; done)"
    ply line.ply "$(printf '0 0.1 0\n0.05 0.12 0\n0.1 0.14 0')" "0 1 2"
    for m in point line; do
        out=$("$kdt" "${kdtree[@]}" --model $m.ply --rows sah --csv $m.csv 2>&1) ||
            fail "$m: exit status $?: $out"
        echo "$out"
        cat $m.csv
        grep -q 'nan\|inf' <<<"$out" && fail "$m: a nan or inf in the tables"
        grep -q 'nan\|inf' $m.csv && fail "$m: a nan or inf in the CSV"
        # Table 6.1: diffuse Mrays/s, nodes and tests per diffuse ray.
        grep -q '^| sah | sah | .* | - | - | - | 1 | 1 | ' <<<"$out" || fail "$m: table 6.1"
        # Embree table: diffuse and occluded Mrays/s and every ratio of them.
        grep -q '^| kdtrace row sah (sah) | [0-9.]* | [0-9.]* | [0-9.]* | [0-9.]* | - | - | [0-9.-]* | - | - | 0 | 0 | - | - | - |$' \
            <<<"$out" || fail "$m: Embree table"
        grep -q '^embree,"kdtrace row sah (sah)",\("[0-9.]*",\)\{4\}"-","-",' $m.csv ||
            fail "$m: Embree table CSV"
        # Work table: every column of the diffuse rows.
        grep -q '^| diffuse | - | - | - | - | - | - | - | - | - |$' <<<"$out" || fail "$m: work"
        grep -q '^cost,"diffuse","-","-","-","-","-","-","-","-","-"$' $m.csv ||
            fail "$m: work CSV"
        # Robustness: escape percentages of no aimed rays.
        grep -q '^| kdtrace row sah (sah) | 0 | - | 0 | - | ' <<<"$out" || fail "$m: robustness"
        grep -q '^robustness,"kdtrace row sah (sah)","0","-","0","-",' $m.csv ||
            fail "$m: robustness CSV"
    done
    ;;
converge_quote)
    # The plot runs without a shell: an output directory with a quote and a $(...) gets its
    # plot (or "plot skipped" without matplotlib), and the name runs nothing.
    ply tri.ply "$(printf -- '-1 0 0\n1 0 0\n0 1 0')" "0 1 2"
    o="$dir/q'd \$(touch pwned)/out"
    out=$("$kdt" bench converge tri.ply --no-cache --configs mis,bsdf --width 16 --height 12 \
        --reference-spp 4 --max-spp 8 --threads 1 -o "$o" 2>&1) || fail "exit status $?: $out"
    echo "$out"
    [ -e pwned ] || [ -e "$o/pwned" ] && fail "the output directory's name ran a command"
    python=python3
    [ -x /usr/bin/python3 ] && python=/usr/bin/python3
    if "$python" -c 'import matplotlib' 2>/dev/null; then
        grep -qF "wrote $o/converge.png" <<<"$out" || fail "no plot"
        [ -s "$o/converge.png" ] || fail "no $o/converge.png"
    else
        grep -q "plot skipped: needs python3-matplotlib" <<<"$out" || fail "no skip message"
    fi
    ;;
converge_tiny)
    # Up to 2 spp leaves no point from 4 spp on to fit the slope to: "-", with no verdict, and
    # no nan anywhere (nor in the equal-time ratios).
    ply tri.ply "$(printf -- '-1 0 0\n1 0 0\n0 1 0')" "0 1 2"
    out=$("$kdt" bench converge tri.ply --no-cache --configs mis,bsdf --width 16 --height 12 \
        --reference-spp 4 --max-spp 2 --threads 1 --no-plot -o out 2>&1) || fail "exit status $?: $out"
    echo "$out"
    grep -q 'nan' <<<"$out" && fail "a nan"
    grep -q '^| mis | - | [0-9.]* | [0-9.]* |$' <<<"$out" || fail "the slope of mis is not -"
    grep -q '^| bsdf | - | [0-9.]* | [0-9.]* |$' <<<"$out" || fail "the slope of bsdf is not -"
    ;;
kdtree_subdivide_4)
    # --subdivide takes [0, 4], as `build --subdivide` does: one triangle becomes 256.
    ply tri.ply "$(printf -- '-0.1 0 0\n0.1 0 0\n0 0.2 0')" "0 1 2"
    out=$("$kdt" "${kdtree[@]}" --model tri.ply --subdivide 4 --rows sah --no-embree \
        --no-robustness 2>&1) || fail "exit status $?: $out"
    echo "$out"
    grep -q '^256 triangles; ' <<<"$out" || fail "not 256 triangles"
    ;;
kdtree_subdivide_oom)
    # --subdivide beyond the memory names the model's count and the flag, before any work, as
    # `kdtrace build` does: 200000 triangles (loaded within about 120 MB of address space)
    # become 12.8M, which at about 100 bytes each (one row, no Embree) need far more than the
    # 300 MB that ulimit -v leaves; the check counts the ulimit (it once let them through to run out of
    # memory while subdividing).
    awk -v n=200000 'BEGIN {
        printf "ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\n", 3 * n
        printf "property float z\nelement face %d\nproperty list uchar int vertex_indices\n", n
        printf "end_header\n"
        for (i = 0; i < n; i++) {
            x = (i % 500) * 0.001; y = int(i / 500) * 0.001
            printf "%g %g 0\n%g %g 0\n%g %g 0.0005\n", x, y, x + 0.001, y, x, y + 0.001
        }
        for (i = 0; i < n; i++) printf "3 %d %d %d\n", 3 * i, 3 * i + 1, 3 * i + 2
    }' >big.ply || fail "cannot write big.ply"
    out=$(ulimit -v 300000; "$kdt" "${kdtree[@]}" --model big.ply --subdivide 3 --rows sah \
        --no-embree --no-robustness 2>&1) && fail "exit status 0: $out"
    rm -f big.ply
    echo "$out"
    grep -q '^kdtrace: error: --subdivide 3: 200000 triangles become 12800000, more than the [0-9]* that fit the kd-tree and the memory available' \
        <<<"$out" || fail "no message naming the flag and the counts"
    ;;
*) fail "unknown case $case_name" ;;
esac
echo "PASS: $case_name"
