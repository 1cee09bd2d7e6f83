#!/usr/bin/env bash
# Every image of `render --frames` is its own session: `render --session FRAME` renders that
# frame again bit for bit (its own camera: a turntable's turn, a view's, a session's with the
# command line's camera flags), and its kdtrace:command does so from any directory.
# Usage: frames_session_test.sh KDTRACE WORKDIR MODEL   (prints PASS: frames_session)
set -u
kdtrace=$1 work=$2 model=$3
[ -f "$model" ] || { echo "PASS: frames_session (skipped: no $model)"; exit 0; }
rm -rf "$work" && mkdir -p "$work/other" && cd "$work" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cp "$model" model.ply  # a relative name in the frames' options
common=(render model.ply --width 32 --height 24 --spp 2 --threads 1 --quiet)
# Renders the frames as PNG (with metadata) and as PFM, then each PNG's session as PFM.
check() {  # NAME PATTERN FLAGS...
    local name=$1 pattern=$2 png pfm
    shift 2
    "$kdtrace" "${common[@]}" "$@" -o "$pattern.png" > /dev/null || fail "$name: png frames"
    "$kdtrace" "${common[@]}" "$@" -o "$pattern.pfm" > /dev/null || fail "$name: pfm frames"
    for png in "${pattern%%[%_]*}"_*.png; do
        pfm=${png%.png}.pfm
        "$kdtrace" render --session "$png" --quiet -o "s_$pfm" > /dev/null || fail "$png: session"
        cmp "$pfm" "s_$pfm" || fail "$name: render --session $png differs from the frame"
    done
}
check turntable 't_%d' --frames 4 --turntable
cmp -s t_0.pfm t_2.pfm && fail "turntable frames 0 and 2 are the same image"
check turntable_eye 'e_%d' --frames 3 --turntable --eye 1,2,4 --fov 30
cat > views.json << 'JSON'
{"views": [
  {"name": "front", "eye": [0, 0.8, 4.5], "target": [0, 0.75, 0], "vfov_degrees": 40},
  {"name": "top", "eye": [0.5, 5, 0.5], "target": [0, 0.75, 0], "up": [0, 0, -1], "vfov_degrees": 45}]}
JSON
check views v --frames views:front,top --views views.json --fov 50
echo '{"scene": {"camera": {"eye": [1.5, 1.2, 3.0], "target": [0, 0.7, 0], "up": [0, 1, 0], "vfov_degrees": 35}}, "trace": {"seed": 3}}' > near.json
echo '{"scene": {"camera": {"eye": [-3, 2, -5], "target": [0, 0.7, 0], "up": [0, 1, 0], "vfov_degrees": 30}}}' > far.json
check sessions s --frames sessions:near.json,far.json --target 0,0.5,0
# A frame image holds the keys of a single render of that frame (and its name and how it was
# distributed), with the same scene JSON, camera, seed, samples and passes.
"$kdtrace" "${common[@]}" --view front --views views.json --fov 50 -o single_front.png \
    > /dev/null || fail "single render of view front"
keys() { "$kdtrace" info --all "$1" | sed -n -E 's/^([A-Za-z]+(:[a-z_]+)?): .*/\1/p' | sort; }
values() {  # the lines from kdtrace:scene_json to the next key, and the keys named
    "$kdtrace" info --all "$1" | awk '/^[^ ]/ { on = 0 }
        /^kdtrace:(scene_json|camera|seed|spp|passes): / { on = 1 } on'
}
[ "$(keys v_front.png | grep -v -x -e kdtrace:frame -e kdtrace:distribution)" = \
  "$(keys single_front.png)" ] ||
    fail "v_front.png has the keys $(keys v_front.png | tr '\n' ' '), a single render" \
         "$(keys single_front.png | tr '\n' ' ')"
values v_front.png | grep -q '^kdtrace:passes: [1-9]' || fail "v_front.png: no kdtrace:passes"
[ "$(values v_front.png)" = "$(values single_front.png)" ] ||
    fail "v_front.png: scene JSON, camera, seed, spp or passes differ from a single render's"
# The stored command names the image by its absolute path and renders it from anywhere.
command=$("$kdtrace" info t_2.png | sed -n 's/^kdtrace:command: //p')
[ "$command" = "kdtrace render --session '$work/t_2.png' --spp 2" ] ||
    fail "t_2.png: command '$command'"
(cd other && eval "\"$kdtrace\" ${command#kdtrace } --quiet -o c_2.pfm" > /dev/null) ||
    fail "the stored command failed"
cmp t_2.pfm other/c_2.pfm || fail "the stored command renders another image"
# A frame stopped by --time stores the samples it reached: its command asks for them.
"$kdtrace" render model.ply --width 16 --height 12 --threads 1 --quiet --time 0.2 \
    --frames 1 --turntable -o "tm_%d.png" > /dev/null || fail "--time frames"
spp=$("$kdtrace" info tm_0.png | sed -n 's/^kdtrace:spp: \([0-9]*\)\.0*$/\1/p')
[ -n "$spp" ] || fail "tm_0.png: no whole kdtrace:spp"
command=$("$kdtrace" info tm_0.png | sed -n 's/^kdtrace:command: //p')
[ "$command" = "kdtrace render --session '$work/tm_0.png' --spp $spp" ] ||
    fail "tm_0.png (reached $spp spp): command '$command'"
echo "PASS: frames_session"
