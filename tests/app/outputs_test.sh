#!/bin/bash
# Outputs never destroy inputs: every writing command refuses an output that is one of its
# inputs (by the same path, `..`, a symlink or a hard link) or a FIFO/device, and leaves the
# input byte for byte as it was. Usage: outputs_test.sh KDTRACE WORKDIR.
set -u
kdt=$1 dir=$2
rm -rf "$dir" && mkdir -p "$dir/sub" || exit 1
cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cp /usr/share/assimp/models/PLY/cube.ply m.ply
"$kdt" render m.ply --spp 1 --width 8 --height 8 --quiet --cache-dir cache -o e.pfm >/dev/null ||
    fail "cannot make the probe"
ln -s m.ply link.ply
ln m.ply hard.ply
ln -s e.pfm e_link.pfm
# .json names of the inputs and of a device, for `scene -o` (which takes .json names only).
ln -s m.ply m_link.json
ln m.ply m_hard.json
ln -s e.pfm e_alias.json
ln -s /dev/null null.json
mkfifo fifo.png
printf '{"meshes": [{"file": "m.ply"}], "environment": {"file": "e.pfm"}}\n' >s.json
sum_before=$(md5sum m.ply e.pfm s.json)

# refused EXPECTED-MESSAGE COMMAND...: the command must fail with that message.
refused() {
    local expect=$1
    shift
    out=$("$kdt" "$@" 2>&1) && fail "accepted: $*"
    grep -q -- "$expect" <<<"$out" || fail "$*: expected '$expect', got: $out"
    echo "refused: $* -> $(grep error <<<"$out")"
}
refused "cannot write the tree: it is the input" build m.ply -o m.ply
refused "cannot write the tree: it is the input" build m.ply -o sub/../m.ply
refused "cannot write the tree: it is the input" build m.ply -o link.ply
refused "cannot write the tree: it is the input" build link.ply -o hard.ply
refused "cannot write the scene: it is the input" scene m.ply -o ./m_link.json
refused "cannot write the scene: it is the input" scene s.json -o s.json
refused "cannot write the scene: it is the input m.ply" scene s.json -o m_hard.json
refused "cannot write the scene: it is the input e.pfm" scene s.json -o sub/../e_alias.json
refused "cannot write the image: it is the input" render m.ply --env e.pfm -o e.pfm --spp 1 --quiet
refused "cannot write the image: it is the input" render s.json -o e_link.pfm --spp 1 --quiet
refused "cannot write the image: is a FIFO" render m.ply -o fifo.png --spp 1 --quiet
refused "cannot write the scene: is a symlink to a character device" scene m.ply -o null.json
refused "cannot write the CSV table: it is the input" bench load m.ply --csv link.ply --repeat 1
# Files the options come from: --session, --views (with or without --view; with --mpi in
# tests/mpi/mpi_test.sh, stats_output).
printf '{"trace":{"seed":3}}\n' >session.png
printf '{"views":[{"name":"A","eye":[0,2,3],"target":[0,0,0],"up":[0,1,0],"vfov_degrees":40}]}\n' >views.png
refused "cannot write the image: it is the input" render m.ply --session session.png \
    -o session.png --spp 1 --quiet
refused "cannot write the image: it is the input" render m.ply --views views.png --view A \
    -o views.png --spp 1 --quiet
refused "cannot write the image: it is the input" render m.ply --views views.png \
    -o sub/../views.png --spp 1 --quiet
# bench load --make-binary DIR: a copy DIR/STEM_le.ply must not replace an input.
mkdir mb && cp m.ply mb/a.ply && cp m.ply mb/a_le.ply && printf 'comment\n' >>mb/a_le.ply
sum_before="$sum_before $(md5sum session.png views.png mb/a.ply mb/a_le.ply)"
refused "cannot write the binary copy: it is the input mb/a_le.ply" bench load mb/a_le.ply \
    mb/a.ply --make-binary mb --no-assimp --repeat 1
refused "it is also the copy of mb/a.ply" bench load mb/a.ply m.ply sub/../mb/a.ply \
    --make-binary sub --no-assimp --repeat 1
[ -e sub/a_le.ply ] && fail "bench load wrote a copy before refusing"
[ "$(md5sum m.ply e.pfm s.json) $(md5sum session.png views.png mb/a.ply mb/a_le.ply)" = \
    "$sum_before" ] || fail "an input changed"
[ -p fifo.png ] || fail "the FIFO was replaced"
[ -L link.ply ] || fail "the symlink was replaced"

# Overwriting an output that is no input keeps its mode.
touch keep.json && chmod 604 keep.json
"$kdt" scene m.ply -o keep.json >/dev/null || fail "scene -o keep.json failed"
[ "$(stat -c %a keep.json)" = 604 ] || fail "mode of keep.json is $(stat -c %a keep.json)"
grep -q '"meshes"' keep.json || fail "keep.json not written"
[ -z "$(find . -name '*.tmp*')" ] || fail "temporary files left"
echo "PASS: outputs"
