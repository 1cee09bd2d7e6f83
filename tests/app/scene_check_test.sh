#!/bin/bash
# `kdtrace scene` checks every file a scene references as `render` does, naming the scene
# file and the key. Usage: scene_check_test.sh KDTRACE WORKDIR.
set -u
kdt=$1 dir=$2
rm -rf "$dir" && mkdir -p "$dir/probe_dir.hdr" || exit 1
cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cp /usr/share/assimp/models/PLY/cube.ply cube.ply
mkfifo fifo.hdr fifo.ply
printf '#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X x\n' >corrupt.hdr
"$kdt" render cube.ply --spp 1 --width 4 --height 2 --quiet --cache-dir cache -o good.pfm \
    >/dev/null || fail "cannot make the probe"
# check SCENE-JSON EXPECTED: `kdtrace scene` on it must fail with EXPECTED.
n=0
check() {
    n=$((n + 1))
    printf '%s\n' "$1" >"s$n.json"
    out=$("$kdt" scene "s$n.json" 2>&1) && fail "s$n.json accepted: $1"
    grep -qF -- "$2" <<<"$out" || fail "s$n.json: expected '$2', got: $out"
    echo "refused: $1 -> $out"
}
env() { echo "{\"meshes\": [{\"file\": \"cube.ply\"}], \"environment\": {\"file\": \"$1\"}}"; }
mesh() { echo "{\"meshes\": [{\"file\": \"$1\"}]}"; }
check "$(env missing.hdr)" "s1.json: environment/file: missing.hdr: cannot open file"
check "$(env probe_dir.hdr)" "s2.json: environment/file: probe_dir.hdr: is a directory"
check "$(env fifo.hdr)" "s3.json: environment/file: fifo.hdr: is a FIFO"
check "$(env /dev/zero)" "s4.json: environment/file: /dev/zero: is a character device"
check "$(env corrupt.hdr)" "s5.json: environment/file: "
check "$(mesh missing.ply)" "s6.json: meshes/0/file: "
check "$(mesh fifo.ply)" "s7.json: meshes/0/file: "
check "$(mesh 'cube.ply\u0000.obj')" "s8.json: meshes/0/file: file name contains a control character"
check '{"meshes": [{"file": "cube.ply", "transform": {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0.5,1]}}]}' \
    "s9.json: meshes/0/transform/matrix: the bottom row must be 0 0 0 1"
env good.pfm >ok.json
"$kdt" scene ok.json >/dev/null || fail "a scene with a good probe was refused"
# Names from files reach the terminal escaped (ESC, BEL, U+202E) and whole (a NUL does not
# cut them short), as `info` shows them.
printf '{"name": "a\\u001b[31mred\\u0007\\u202e\\u0000z", "meshes": [{"file": "cube.ply"}]}\n' \
    >named.json
out=$("$kdt" scene named.json 2>&1) || fail "named.json refused: $out"
grep -qF 'scene a\x1b[31mred\x07\u202e\x00z: 1 meshes' <<<"$out" || fail "scene name: $out"
cp cube.ply $'m\e[31m.ply'
out=$("$kdt" scene $'m\e[31m.ply' 2>&1) || fail "m<ESC>.ply refused: $out"
grep -qF '  m\x1b[31m.ply: 12 triangles' <<<"$out" || fail "model name: $out"
for f in named.json $'m\e[31m.ply'; do
    LC_ALL=C grep -q $'[\x01-\x08\x0b-\x1f\x7f]' <("$kdt" scene "$f" 2>&1) &&
        fail "$f: a control byte reached the terminal"
done
echo "PASS: scene checks"
