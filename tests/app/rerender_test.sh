#!/bin/bash
# The command stored in an image (kdtrace:command) renders the same image again, bit for bit,
# and the stored tree parameters are those of the tree used (a --tree file's, not the flags').
# Usage: rerender_test.sh KDTRACE WORKDIR VIEWS_FILE.
set -u
kdt=$1 dir=$2 views=$3
rm -rf "$dir" && mkdir -p "$dir" || exit 1
cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
# A quote in the name: the stored command must quote it for the shell.
model="it's a cube.ply"
cp /usr/share/assimp/models/PLY/cube.ply "$model"
"$kdt" build "$model" --builder thesis --q 0.7 --n0 3 -o t.kdt >/dev/null || fail "build"

# same NAME FLAGS...: renders NAME.exr (for the metadata) and NAME.pfm with FLAGS, runs the
# command stored in NAME.exr writing NAME_again.pfm, and compares the two PFMs.
same() {
    local name=$1
    shift
    local flags=(--width 16 --height 12 --spp 3 --no-cache --quiet "$@")
    "$kdt" render "$model" "${flags[@]}" -o "$name.exr" >/dev/null || fail "$name: render exr"
    "$kdt" render "$model" "${flags[@]}" -o "$name.pfm" >/dev/null || fail "$name: render pfm"
    command=$("$kdt" info "$name.exr" | sed -n 's/^kdtrace:command: //p')
    [ -n "$command" ] || fail "$name: no kdtrace:command"
    command=${command/#kdtrace /\"\$kdt\" }
    eval "$command --quiet -o '${name}_again.pfm'" >/dev/null 2>err.txt ||
        fail "$name: the stored command fails: $command: $(cat err.txt)"
    cmp -s "$name.pfm" "${name}_again.pfm" || fail "$name: another image from: $command"
    echo "same image: $command"
}
same camera --eye 0.1,0.2,3.3 --target 0.01,0,0 --up 0,1,0.1 --fov 33.3333 --threads 1
same view --view B --views "$views" --threads 2
same tree --tree t.kdt --threads 1 --fov 50
same tree_and_flags --tree t.kdt --builder sah --q 0.5 --threads 1
# The per-pixel cap and an adaptive budget decide where these stop: the command keeps them.
same error_cap --error 0.001 --max-spp 8 --threads 1
same adaptive_cap --adaptive --max-spp 2 --threads 1
# Whole-number options are written in digits (--max-spp 100000, not 1e+05).
same integers --max-spp 100000 --threads 1
grep -q -- " --max-spp 100000\( \|$\)" <<<"$command" ||
    fail "whole numbers not written as such: $command"

# A --time render stops where the run happens to be: its session asks for the spp it reached,
# as its command does, so that `--session IMAGE` alone renders the same image as the command.
"$kdt" render "$model" --width 16 --height 12 --time 0.3 --no-cache --quiet -o timed.exr \
    >/dev/null || fail "timed: render"
params=$("$kdt" info --all timed.exr | sed -n 's/^kdtrace:params: //p')
grep -q '"stop":{[^}]*"seconds":0.0' <<<"$params" || fail "timed: the session keeps --time: $params"
"$kdt" render --session timed.exr --quiet -o timed_session.pfm >/dev/null ||
    fail "timed: render --session"
command=$("$kdt" info timed.exr | sed -n 's/^kdtrace:command: //p')
eval "${command/#kdtrace /\"\$kdt\" } --quiet -o timed_command.pfm" >/dev/null ||
    fail "timed: the stored command fails: $command"
cmp -s timed_session.pfm timed_command.pfm || fail "timed: --session and $command differ"

params=$("$kdt" info --all tree_and_flags.exr | sed -n 's/^kdtrace:params: //p')
grep -q '"tree":{"builder":"thesis",[^}]*"n0":3,"q":0.7,' <<<"$params" ||
    fail "the metadata does not describe the tree file: $params"
# The same for the frames of --frames (app/mpi_cli.cpp).
"$kdt" render "$model" --width 8 --height 6 --spp 1 --no-cache --quiet --tree t.kdt --q 0.5 \
    --frames 1 --turntable -o "frame%d.exr" >/dev/null 2>&1 || fail "render --frames"
params=$("$kdt" info --all frame0.exr | sed -n 's/^kdtrace:params: //p')
grep -q '"tree":{"builder":"thesis",[^}]*"n0":3,"q":0.7,' <<<"$params" ||
    fail "the frame's metadata does not describe the tree file: $params"
echo "PASS: rerender"
