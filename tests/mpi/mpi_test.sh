#!/usr/bin/env bash
# MPI smoke tests of `kdtrace render --mpi` and `--frames` (registered by tests.cmake).
# Usage: mpi_test.sh CASE KDTRACE MPIEXEC WORKDIR MODEL
# Exits 0 on success, 1 on failure, 77 (skip) when MPIEXEC cannot be run.
set -u
case_name=$1 kdtrace=$2 mpiexec=$3 work=$4 model=$5
command -v "$mpiexec" > /dev/null || { echo "skip: $mpiexec not found"; exit 77; }
mkdir -p "$work" && cd "$work" || exit 1
mpi() { local n=$1; shift; timeout -k 5 100 "$mpiexec" --oversubscribe --allow-run-as-root -np "$n" "$kdtrace" "$@"; }
fail() { echo "FAIL: $*"; exit 1; }
# A small image with partial tiles at the right and bottom, several passes per pixel.
common=(render "$model" --no-cache --width 72 --height 40 --spp 5 --spp-per-pass 2 --seed 11
        --threads 1 --quiet)

# A views file with three cameras on the model (Wuson: x [-0.46, 0.46], y [0, 1.52],
# z [-1.62, 1.62]).
views() {
    cat > views.json << 'EOF'
{"views": [
  {"name": "front", "eye": [0, 0.8, 4.5], "target": [0, 0.75, 0], "vfov_degrees": 40},
  {"name": "side", "eye": [4.5, 1.0, 0.3], "target": [0, 0.75, 0], "vfov_degrees": 40},
  {"name": "top", "eye": [0.5, 5, 0.5], "target": [0, 0.75, 0], "up": [0, 0, -1], "vfov_degrees": 45}]}
EOF
}
# Two session files of other sizes, seeds and cameras; "far" asks for 64 spp (the command
# line's --spp wins); sub/near.json has the same stem as near.json.
sessions() {
    cat > near.json << 'EOF'
{"scene": {"width": 40, "height": 30, "camera": {"eye": [1.5, 1.2, 3.0], "target": [0, 0.7, 0], "up": [0, 1, 0], "vfov_degrees": 35}}, "trace": {"seed": 3}}
EOF
    cat > far.json << 'EOF'
{"scene": {"width": 56, "height": 24, "camera": {"eye": [-3, 2, -5], "target": [0, 0.7, 0], "up": [0, 1, 0], "vfov_degrees": 30}}, "trace": {"seed": 4}, "stop": {"spp": 64}}
EOF
    mkdir -p sub && cp near.json sub/near.json
}

# Each FAULT:PROBLEM makes rank 2's message malformed (--mpi-inject 2:FAULT) in a 3-rank
# render, which must end with status 1, no crash, no image, no interrupt or timeout reported,
# and exactly one error line, "MALFORMED: PROBLEM". Usage: malformed_ends MALFORMED CASE...
malformed_ends() {
    local malformed=$1 t out rc
    shift
    for t in "$@"; do
        rm -f x.pfm
        out=$(mpi 3 "${common[@]}" --mpi --timeout 30 --mpi-inject "2:${t%%:*}" -o x.pfm 2>&1); rc=$?
        echo "$out"
        [ $rc -eq 1 ] || fail "${t%%:*}: exit status $rc, not 1"
        grep -q "exited on signal\|Segmentation\|terminate called" <<< "$out" && fail "${t%%:*}: a rank crashed"
        [ "$(grep -c 'kdtrace: error:' <<< "$out")" -eq 1 ] || fail "${t%%:*}: not exactly one error line"
        grep -q "^kdtrace: error: $malformed: ${t#*:}$" <<< "$out" || fail "${t%%:*}: no error line naming rank 2"
        grep -q "interrupted\|timeout" <<< "$out" && fail "${t%%:*}: an interrupt or timeout was reported"
        [ -e x.pfm ] && fail "${t%%:*}: an image was written"
    done
}

# Tiles per rank from the "mpi: rank R: N tiles" lines.
tiles_of() { sed -n "s/^mpi: rank $2: \([0-9]*\) tiles.*/\1/p" "$1"; }

case $case_name in
identity_*)
    # Bitwise identity with the single-process render for N = 1..4.
    dist=${case_name#identity_}
    "$kdtrace" "${common[@]}" -o ref.pfm > /dev/null || fail "single-process render"
    for n in 1 2 3 4; do
        rm -f "mpi_$n.pfm"
        mpi "$n" "${common[@]}" --mpi --distribution "$dist" -o "mpi_$n.pfm" > "log_$n.txt" 2>&1 ||
            { cat "log_$n.txt"; fail "$dist with $n ranks exited non-zero"; }
        cmp ref.pfm "mpi_$n.pfm" || fail "$dist with $n ranks differs from the single-process image"
        grep -q "mpi: $n ranks, $dist, 15 tiles" "log_$n.txt" || { cat "log_$n.txt"; fail "summary"; }
    done
    # A different seed changes the image: the comparison can fail.
    mpi 2 "${common[@]}" --seed 12 --mpi --distribution "$dist" -o other.pfm > /dev/null 2>&1
    cmp -s ref.pfm other.pfm && fail "seed 12 rendered the same image as seed 11"
    echo "ok: $dist bitwise identical for 1..4 ranks" ;;
frames)
    args=("${common[@]}" --frames 5 --turntable)
    "$kdtrace" "${args[@]}" -o "local_%02d.pfm" > /dev/null || fail "local frames"
    cmp -s local_00.pfm local_01.pfm && fail "turntable frames 0 and 1 are the same image"
    "$kdtrace" "${common[@]}" -o single.pfm > /dev/null || fail "single render"
    cmp single.pfm local_00.pfm || fail "frame 0 differs from the unrotated render"
    for run in 2:dynamic 3:dynamic 3:strips 3:interleaved; do
        n=${run%%:*} dist=${run#*:}
        rm -f mpi_*.pfm
        mpi "$n" "${args[@]}" --mpi --distribution "$dist" -o "mpi_%02d.pfm" > "log_$run.txt" 2>&1 ||
            { cat "log_$run.txt"; fail "frames with $n ranks, $dist"; }
        for f in 00 01 02 03 04; do
            cmp "local_$f.pfm" "mpi_$f.pfm" || fail "frame $f with $n ranks, $dist differs"
        done
        grep -q "mpi: $n ranks, $dist, 5 frames" "log_$run.txt" || { cat "log_$run.txt"; fail "summary"; }
    done
    # Strips give each rank consecutive frames: 1, 2 and 2 of 5 over 3 ranks.
    grep -q "mpi: rank 0: 1 frames" "log_3:strips.txt" || fail "strips: rank 0 did not render 1 frame"
    echo "ok: 5 turntable frames identical locally and over 2 and 3 ranks, every distribution" ;;
throttle)
    # Rank 1 sleeps (F - 1)x its render time after each tile. Under dynamic it takes the 2
    # tiles it requests ahead, then one more per F tile times while the others drain the
    # queue; strips and interleaved give it its fixed 30 or 27 whatever its speed. The check
    # is a wide margin, not a race between ranks: the camera fills every tile with the model
    # (3-5 ms each, above the scheduler's time slice and the throttle's 1 ms sleep), and with
    # F = 100 rank 1 reaches half its static share (13) only if the other two together take
    # over 16x its tile time per tile (its 11 results after the first 2 span 1100 tile times,
    # in which they did at most 67 tiles). Beside three busy loops (load 10 on 2 cores) it took
    # 2-6 tiles in 11 runs; the old check (fewer tiles than each other rank, F = 8, 0.3 ms
    # tiles mostly of background) failed there 9 runs in 9.
    big=(render "$model" --no-cache --width 160 --height 128 --spp 32 --threads 1 --quiet
         --eye 5,0.95,0 --target 0,0.95,0 --fov 8 --mpi)
    mpi 3 "${big[@]}" --throttle 1:100 -o t_dynamic.pfm > t_dynamic.txt 2>&1 ||
        { cat t_dynamic.txt; fail "dynamic throttled"; }
    # The static runs only count tiles: a milder throttle keeps them short.
    for dist in strips interleaved; do
        mpi 3 "${big[@]}" --throttle 1:4 --distribution "$dist" -o "t_$dist.pfm" \
            > "t_$dist.txt" 2>&1 || { cat "t_$dist.txt"; fail "$dist throttled"; }
    done
    cat t_dynamic.txt t_strips.txt t_interleaved.txt
    t0=$(tiles_of t_dynamic.txt 0) t1=$(tiles_of t_dynamic.txt 1) t2=$(tiles_of t_dynamic.txt 2)
    [ $((t0 + t1 + t2)) -eq 80 ] || fail "dynamic: ranks did $t0 + $t1 + $t2 tiles, not 80"
    [ "$t1" -le 13 ] ||
        fail "dynamic: throttled rank 1 did $t1 tiles (ranks 0 and 2: $t0, $t2), over half its static share"
    # 80 tiles: strips of 10 tile columns give rows 0-2, 3-5, 6-7; interleaved 27, 27, 26.
    [ "$(tiles_of t_strips.txt 1)" -eq 30 ] || fail "strips: rank 1 did not do its 30 tiles"
    [ "$(tiles_of t_interleaved.txt 1)" -eq 27 ] || fail "interleaved: rank 1 did not do 27 tiles"
    cmp t_dynamic.pfm t_strips.pfm && cmp t_dynamic.pfm t_interleaved.pfm ||
        fail "throttled renders differ"
    echo "ok: dynamic gave the throttled rank $t1 tiles (others $t0, $t2), static 30 and 27" ;;
fail_load)
    out=$(mpi 3 "${common[@]}" --mpi --mpi-inject 1:load -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a rank that cannot load gave exit status 0"
    [ "$(grep -c 'kdtrace: error:' <<< "$out")" -eq 1 ] || fail "not exactly one error message"
    grep -q "kdtrace: error: rank 1 of 3 could not load the scene: .*kdtrace-injected-fault.*cannot open" <<< "$out" ||
        fail "message does not name rank 1 and the reason"
    # Nothing else: mpirun's SIGTERM to ranks still finalizing is no interrupt.
    [ "$(grep -c '^kdtrace: ' <<< "$out")" -eq 1 ] || fail "a line besides the error" ;;
fail_hash)
    out=$(mpi 3 "${common[@]}" --mpi --mpi-inject 2:hash -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a rank with another tree gave exit status 0"
    grep -q "kdtrace: error: rank 2 of 3 sees a different kd-tree than the other ranks" <<< "$out" ||
        fail "message does not name rank 2"
    # Rank 0 is the odd one: it is named, not rank 1.
    out=$(mpi 3 "${common[@]}" --mpi --mpi-inject 0:hash -o x.pfm 2>&1)
    grep -q "kdtrace: error: rank 0 of 3 sees a different kd-tree than the other ranks" <<< "$out" ||
        { echo "$out"; fail "message does not name rank 0"; } ;;
env_mismatch)
    # Ranks that see another environment map under the same relative name stop with one
    # message naming the file and the odd rank, instead of rendering a mixed image.
    mkdir -p a b
    small=(render "$model" --no-cache --width 16 --height 8 --spp 1 --threads 1 --quiet)
    "$kdtrace" "${small[@]}" --seed 1 -o a/p.pfm > /dev/null &&
        "$kdtrace" "${small[@]}" --seed 2 -o b/p.pfm > /dev/null &&
        cp a/p.pfm p.pfm || fail "making the maps"
    cmp -s a/p.pfm b/p.pfm && fail "the two maps are the same"
    mpmd() {  # ranks in a/, then ranks in b/
        timeout -k 5 100 "$mpiexec" --oversubscribe --allow-run-as-root \
            -np "$1" -wdir "$work/a" "$kdtrace" "${common[@]}" --env p.pfm --mpi -o "$work/x.pfm" : \
            -np "$2" -wdir "$work/b" "$kdtrace" "${common[@]}" --env p.pfm --mpi -o "$work/x.pfm"
    }
    for split in "1 1:ranks 0 and 1 of 2 see a different environment map p.pfm" \
        "1 2:rank 0 of 3 sees a different environment map p.pfm than the other ranks" \
        "2 1:rank 2 of 3 sees a different environment map p.pfm than the other ranks"; do
        rm -f x.pfm
        out=$(mpmd ${split%%:*} 2>&1); rc=$?
        echo "$out"
        [ $rc -ne 0 ] || fail "${split%%:*}: exit status 0"
        grep -q "kdtrace: error: ${split#*:}" <<< "$out" || fail "${split%%:*}: message"
        [ -e x.pfm ] && fail "${split%%:*}: an image was written"
    done
    # The same map everywhere renders as before.
    cp a/p.pfm b/p.pfm
    mpmd 1 1 > log.txt 2>&1 || { cat log.txt; fail "the same map on both ranks"; }
    "$kdtrace" "${common[@]}" --env p.pfm -o ref.pfm > /dev/null && cmp ref.pfm x.pfm ||
        fail "the image differs from the single-process render"
    echo "ok: a different environment map is named with the odd rank" ;;
fail_missing)
    out=$(mpi 2 render "$work/no_such_model.ply" --no-cache --spp 1 --mpi -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a missing model gave exit status 0"
    grep -q "kdtrace: error: all 2 ranks failed to load the scene: .*no_such_model.ply" <<< "$out" ||
        fail "message" ;;
timeout)
    # Rank 2 sleeps 100000x its render time: the run is stuck until --timeout ends it. Its
    # tiles are dealt out in advance (interleaved): under the dynamic queue, a rank 2 that
    # starts late on a loaded machine may find every tile taken, sleep never, and the run end.
    out=$(mpi 3 "${common[@]}" --mpi --distribution interleaved --throttle 2:100000 --timeout 6 \
        -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a timed-out run gave exit status 0"
    grep -q "kdtrace: error: --timeout 6 s reached: rank 2 of 3 had not returned its work; ending every rank" <<< "$out" ||
        fail "no timeout message naming rank 2" ;;
bad_result|bad_work)
    # A malformed message (a test fault: --mpi-inject RANK:result-* makes that worker's first
    # result malformed, RANK:work-* rank 0's first reply to it) is one error line naming the
    # rank and the problem: from rank 0 for a result, from the worker for its work. Status 1,
    # no image, no hang (--timeout would name the ranks instead). Tiles: strips give ranks 1
    # and 2 a row of 5 tiles each, whatever the timing; frames: frames 1 and 2 go to rank 1,
    # and frame 0, rendered by rank 0, may be written, as the local render's.
    from0="rank 0: a result from rank 2 of 3 is malformed"
    to2="rank 2: a work message from rank 0 is malformed"
    if [ "$case_name" = bad_result ]; then
        tiles=("result-item:$from0: item 2147483647 was not given to it or was returned before"
               "result-header:$from0: 6 bytes, shorter than its 8-byte header"
               "result-ids:$from0: [0-9]* bytes, but its header announces [0-9]* items and asks for 1"
               "result-short:$from0: 3072 bytes of results for 1 item, not 6144")  # a 16x8 tile
        frames=(result-item result-header result-ids result-short)
    else
        tiles=("work-item:$to2: item 15 is outside \[0, 15)"
               "work-repeat:$to2: item 10 was given before"
               "work-count:$to2: 3 items, more than the 2 this rank asked for"
               "work-bytes:$to2: 10 bytes, not a whole number of 4-byte item ids")
        frames=(work-item work-count work-bytes)  # a frame worker asks for one: no repeat
    fi
    ended() {  # WHAT RC OUTPUT EXPECTED-ERROR
        [ "$2" -eq 1 ] || fail "$1: exit status $2, not 1"
        grep -q "exited on signal\|Segmentation" <<< "$3" && fail "$1: a rank crashed"
        [ "$(grep -c 'kdtrace: error:' <<< "$3")" -eq 1 ] || fail "$1: not exactly one error line"
        grep -q "^kdtrace: error: $4$" <<< "$3" || fail "$1: no error line '$4'"
        # The cause alone: not also an "interrupted (SIGTERM)" from the SIGTERM mpirun sends
        # the other ranks once one has exited with status 1.
        [ "$(grep -c '^kdtrace: ' <<< "$3")" -eq 1 ] || fail "$1: a line besides the error"
    }
    # The first case with mpirun's SIGKILL 4 s after its SIGTERM instead of 1 s, as on a
    # loaded machine: the workers, which wait 2 s for it before they report a signal as their
    # own, must have ended silently once rank 0 said the job ended.
    kill_after=4
    for t in "${tiles[@]}"; do
        rm -f x.pfm
        out=$(OMPI_MCA_odls_base_sigkill_timeout=$kill_after mpi 3 "${common[@]}" --mpi \
            --distribution strips --timeout 30 --mpi-inject "2:${t%%:*}" -o x.pfm 2>&1); rc=$?
        kill_after=1
        echo "$out"
        ended "tiles, ${t%%:*}" $rc "$out" "${t#*:}"
        [ -e x.pfm ] && fail "tiles, ${t%%:*}: an image was written"
    done
    "$kdtrace" "${common[@]}" --frames 3 --turntable -o "local_%d.pfm" > /dev/null || fail "local frames"
    for f in "${frames[@]}"; do
        rm -f f_*.pfm
        out=$(mpi 2 "${common[@]}" --mpi --frames 3 --turntable --distribution strips --timeout 30 \
            --mpi-inject "1:$f" -o "f_%d.pfm" 2>&1); rc=$?
        echo "$out"
        [ "$case_name" = bad_result ] && who="rank 0: a result from rank 1 of 2" ||
            who="rank 1: a work message from rank 0"
        ended "frames, $f" $rc "$out" "$who is malformed: .*"
        ls f_1.pfm f_2.pfm 2> /dev/null && fail "frames, $f: rank 1's frames were written"
        [ ! -e f_0.pfm ] || cmp f_0.pfm local_0.pfm || fail "frames, $f: frame 0 differs"
    done
    echo "ok: malformed messages end the job with one error naming the rank" ;;
bad_options)
    # Rank 0's options message to rank 2 is malformed (a test fault, --mpi-inject
    # 2:options-*): shorter than its header, a text shorter or longer than its header
    # announces, an absurd announced length. Rank 2 checks it before it trusts or allocates
    # anything, and every rank stops with one error line naming rank 2: status 1, no crash,
    # no image, no hang (--timeout would name the ranks instead).
    malformed_ends "rank 2 of 3 could not start: the options from rank 0 are malformed" \
        "options-header:6 bytes, shorter than its 8-byte header" \
        "options-short:its header announces [0-9]* bytes, but [0-9]* bytes follow it" \
        "options-long:its header announces [0-9]* bytes, but [0-9]* bytes follow it" \
        "options-huge:its header announces 1152921504606846976 bytes, more than the 16777216 bytes a rank accepts"
    # The lengths in the short and long messages: the header's is the text's, the others not.
    out=$(mpi 2 "${common[@]}" --mpi --mpi-inject 1:options-long -o x.pfm 2>&1)
    n=$(sed -n 's/.*announces \([0-9]*\) bytes, but \([0-9]*\) bytes follow.*/\1 \2/p' <<< "$out")
    [ -n "$n" ] && [ $((${n#* } - ${n% *})) -eq 8 ] || { echo "$out"; fail "options-long: not 8 bytes more"; }
    echo "ok: malformed options messages end the job with one error naming the rank" ;;
bad_log)
    # Rank 2's load log to rank 0 is malformed (a test fault, --mpi-inject 2:log-*): shorter
    # than its header, a text shorter or longer than its header announces, an absurd
    # announced length. Rank 0 checks it before it trusts or allocates anything, and every
    # rank stops with one error line naming rank 2: status 1, no crash, no image, no hang.
    malformed_ends "rank 0 of 3 could not read the load logs: the load log from rank 2 is malformed" \
        "log-header:6 bytes, shorter than its 8-byte header" \
        "log-short:its header announces [0-9]* bytes*, but [0-9]* bytes follow it" \
        "log-long:its header announces [0-9]* bytes, but [0-9]* bytes follow it" \
        "log-huge:its header announces 1152921504606846976 bytes, more than the 8192 bytes a rank accepts"
    # The short and long texts differ from the announced length by what the fault says; the
    # log is not empty (the load says what it did), so half of it is another length.
    out=$(mpi 2 "${common[@]}" --mpi --mpi-inject 1:log-long -o x.pfm 2>&1)
    n=$(sed -n 's/.*announces \([0-9]*\) bytes, but \([0-9]*\) bytes follow.*/\1 \2/p' <<< "$out")
    [ -n "$n" ] && [ $((${n#* } - ${n% *})) -eq 8 ] || { echo "$out"; fail "log-long: not 8 bytes more"; }
    # Rank 0 sends no log: the fault is refused there.
    out=$(mpi 2 "${common[@]}" --mpi --mpi-inject 0:log-short -o x.pfm 2>&1)
    grep -q "only a worker sends results and load logs" <<< "$out" || { echo "$out"; fail "0:log-short accepted"; }
    echo "ok: malformed load logs end the job with one error naming the rank" ;;
orphan)
    # Rank 0 stuck (a test fault, --mpi-inject 1:orphan: rank 0 sends rank 1 a malformed first
    # work message, then sleeps without polling): rank 1's failure line never reaches rank 0,
    # so rank 1 prints it itself once KDT_MPI_FAILURE_GRACE (1 s here; 10 s by default) has
    # passed, and exits with status 1; mpirun then ends rank 0, which reports that as an
    # interrupt. No --timeout: the fallback alone must end the job; `timeout` ends a hang
    # (status 124). Strips: rank 1 has its own tiles, so it is sent work whatever the timing.
    rm -f x.pfm
    out=$(KDT_MPI_FAILURE_GRACE=1 timeout -k 5 60 "$mpiexec" --oversubscribe --allow-run-as-root \
        -x KDT_MPI_FAILURE_GRACE -np 2 "$kdtrace" "${common[@]}" --mpi --distribution strips \
        --mpi-inject 1:orphan -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 124 ] && [ $rc -ne 137 ] || fail "the job hung until timeout ended it"
    [ $rc -eq 1 ] || fail "exit status $rc, not 1"
    grep -q "exited on signal\|Segmentation\|terminate called" <<< "$out" && fail "a rank crashed"
    [ "$(grep -c 'kdtrace: error:' <<< "$out")" -eq 1 ] || fail "not exactly one error line"
    grep -q "^kdtrace: error: rank 1: a work message from rank 0 is malformed: item 15 is outside \[0, 15)$" \
        <<< "$out" || fail "no error line from rank 1"
    grep -q "timeout" <<< "$out" && fail "a timeout was reported"
    [ -e x.pfm ] && fail "an image was written"
    # The grace is checked like any number; rank 0 is no worker to orphan.
    out=$(KDT_MPI_FAILURE_GRACE=-1 mpi 2 "${common[@]}" --mpi -o x.pfm 2>&1)
    grep -q "KDT_MPI_FAILURE_GRACE must be seconds in \[0, 3600\] (got '-1')" <<< "$out" ||
        { echo "$out"; fail "KDT_MPI_FAILURE_GRACE=-1 accepted"; }
    out=$(mpi 2 "${common[@]}" --mpi --mpi-inject 0:orphan -o x.pfm 2>&1)
    grep -q "0:orphan: a stuck rank 0 orphans a worker" <<< "$out" || { echo "$out"; fail "0:orphan accepted"; }
    echo "ok: a worker orphaned by a stuck rank 0 ends the job itself with its error" ;;
timeout_stall)
    # A rank whose load never ends (a test fault, not timing): the others time out in the
    # load check and the job ends with rank 0's message and status 1, not a crash in
    # MPI_Finalize (an abandoned all-gather); rank 0 stalled ends it through its watchdog.
    for r in 2 0; do
        out=$(mpi 3 "${common[@]}" --mpi --mpi-inject "$r:stall" --timeout 1 -o x.pfm 2>&1); rc=$?
        echo "$out"
        [ $rc -eq 1 ] || fail "rank $r stalled: exit status $rc, not 1"
        grep -q "Segmentation" <<< "$out" && fail "rank $r stalled: a crash"
        [ "$(grep -c 'kdtrace: error: --timeout 1 s reached' <<< "$out")" -eq 1 ] ||
            fail "rank $r stalled: not exactly one timeout message"
    done
    # Rank 2 alone is named: the timeout leaves ranks 0 and 1 time to load on a loaded machine.
    out=$(mpi 3 "${common[@]}" --mpi --mpi-inject 2:stall --timeout 4 -o x.pfm 2>&1)
    grep -q "rank 2 of 3 had not finished (load the scene)" <<< "$out" ||
        { echo "$out"; fail "the message does not name rank 2"; }
    [ -e x.pfm ] && fail "an image was written"
    echo "ok: a stalled load ends the job with status 1" ;;
timeout_stop)
    # A worker hung with work in hand: rank 0 names it and the job ends; the
    # healthy ranks do not wait in MPI_Finalize for it. Rank 1's tiles are dealt out in
    # advance (interleaved): under the dynamic queue rank 0 renders all 15 tiles in a few ms,
    # so a rank 1 descheduled that long after the start finds none, never stops, and the run
    # succeeds (a 30 ms sleep before its first request did so every time). The timeout leaves
    # rank 2 seconds to load and return its 5 tiles on a loaded machine, so that it alone is
    # named.
    start=$(date +%s)
    mpi 3 "${common[@]}" --mpi --distribution interleaved --mpi-inject 1:stop --timeout 4 \
        -o x.pfm > log.txt 2>&1 &
    launcher=$!
    # Open MPI 4.1.4's mpirun now and then hangs ending such a job with every rank gone
    # (docs/mpi.md): once no rank of this job (the only one injecting 1:stop) has run for 10 s,
    # mpirun is ended and the ranks' part judged, as for its crash below.
    of_job() {  # PROCESS-NAME-REGEX: the pids of such processes of this job
        local p
        for p in $(pgrep -x "$1"); do
            tr '\0' ' ' < /proc/$p/cmdline 2> /dev/null |
                grep -q -- "--mpi-inject 1:stop --timeout 4" && echo $p
        done
    }
    seen=0 gone=0 hung=0
    while kill -0 $launcher 2> /dev/null; do
        if [ -n "$(of_job kdtrace)" ]; then
            seen=1 gone=0
        elif [ $seen -eq 0 ]; then
            :  # not started yet
        elif [ $gone -eq 0 ]; then
            gone=$(date +%s)
        elif [ $(($(date +%s) - gone)) -ge 10 ]; then
            hung=1
            kill -KILL $(of_job 'mpirun|mpiexec|orterun') 2> /dev/null
            break
        fi
        sleep 0.5
    done
    wait $launcher; rc=$?
    [ $hung -eq 1 ] && { echo "note: mpirun hung after every rank had ended (Open MPI bug)"; rc=1; }
    out=$(cat log.txt)
    echo "$out"
    # Open MPI 4.1.4's mpirun itself sometimes segfaulted in PMIx_server_finalize while it
    # ended such a job (docs/mpi.md; once in a CI run here). Tolerated only when
    # the backtrace is mpirun's own and no rank died of a signal.
    if [ $rc -eq 139 ] && grep -q "PMIx_server_finalize" <<< "$out" &&
        grep -q "\] \[ *[0-9]*\] /usr/bin/mpi\(run\|exec\)(" <<< "$out" &&
        ! grep -q "exited on signal" <<< "$out"; then
        echo "note: mpirun crashed in PMIx_server_finalize after the job ended (Open MPI bug)"
        rc=1
    fi
    [ $rc -eq 1 ] || fail "exit status $rc, not 1"
    grep -q "kdtrace: error: --timeout 4 s reached: rank 1 of 3 had not returned its work; ending every rank" \
        <<< "$out" || fail "the message does not name rank 1"
    [ $(($(date +%s) - start)) -lt 60 ] || fail "the job took a minute to end"
    echo "ok: a hung worker is named and the job ends" ;;
refuse_adaptive)
    # A tile's adaptive decisions read its neighbours across tile borders: refused for tiles.
    for flags in "--error 0.1" "--adaptive"; do
        out=$(mpi 2 "${common[@]}" $flags --mpi -o x.pfm 2>&1); rc=$?
        echo "$out"
        [ $rc -ne 0 ] || fail "$flags with a tiled --mpi render gave exit status 0"
        grep -q "kdtrace: error: all 2 ranks failed to start: a tiled render (--mpi without --frames) takes a fixed stop.spp.*3x3 neighbourhood" <<< "$out" ||
            fail "message for $flags"
    done
    # A time limit depends on each rank's speed: refused for frames too.
    out=$(mpi 2 "${common[@]}" --frames 2 --turntable --time 1 --mpi -o "t_%d.pfm" 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "--time with a frame farm gave exit status 0"
    grep -q "kdtrace: error: all 2 ranks failed to start: a frame farm (--mpi --frames) cannot stop on stop.seconds (--time)" <<< "$out" ||
        fail "message for --time"
    [ -e t_0.pfm ] && fail "a refused run wrote a frame"
    echo "ok: adaptive tiles and timed frames refused on every rank" ;;
views)
    # --frames views: each frame is bitwise the render of that one --view, locally and over
    # 3 and 2 ranks; outputs are named after the views, or numbered by a pattern.
    views
    names=(front side top)
    for v in "${names[@]}"; do
        "$kdtrace" "${common[@]}" --views views.json --view "$v" -o "single_$v.pfm" > /dev/null ||
            fail "single render of view $v"
    done
    cmp -s single_front.pfm single_side.pfm && fail "views front and side rendered the same image"
    "$kdtrace" "${common[@]}" --views views.json --frames views:all -o local.pfm > /dev/null ||
        fail "local views:all"
    for v in "${names[@]}"; do cmp "single_$v.pfm" "local_$v.pfm" || fail "local frame $v differs"; done
    for run in 3:dynamic 2:strips; do
        n=${run%%:*} dist=${run#*:}
        rm -f mpi_*.pfm
        mpi "$n" "${common[@]}" --views views.json --frames views:top,front,side --mpi \
            --distribution "$dist" -o "mpi_%02d.pfm" > "log_$n.txt" 2>&1 ||
            { cat "log_$n.txt"; fail "views over $n ranks"; }
        cmp single_top.pfm mpi_00.pfm && cmp single_front.pfm mpi_01.pfm &&
            cmp single_side.pfm mpi_02.pfm || fail "views over $n ranks, $dist differ"
        grep -q "mpi: $n ranks, $dist, 3 frames" "log_$n.txt" || { cat "log_$n.txt"; fail "summary"; }
    done
    echo "ok: 3 views identical to single renders, locally and over 3 and 2 ranks" ;;
sessions)
    # --frames sessions: frame i is `render --session FILE_i` with the same other flags:
    # the sessions' own sizes, seeds and cameras, and the command line's --spp over theirs.
    sessions
    flags=(render "$model" --no-cache --threads 1 --quiet --spp 3)
    for s in near far; do
        "$kdtrace" "${flags[@]}" --session "$s.json" -o "single_$s.pfm" > /dev/null ||
            fail "single render of session $s"
    done
    cmp -s single_near.pfm single_far.pfm && fail "the two sessions rendered the same image"
    # far.json's own 64 spp give another image: the comparisons below see the --spp override.
    "$kdtrace" render "$model" --no-cache --threads 1 --quiet --session far.json \
        -o own_far.pfm > /dev/null || fail "single render of session far at its own spp"
    cmp -s own_far.pfm single_far.pfm && fail "--spp 3 did not override far.json's 64 spp"
    "$kdtrace" "${flags[@]}" --frames sessions:near.json,far.json -o local.pfm > /dev/null ||
        fail "local sessions"
    cmp single_near.pfm local_near.pfm && cmp single_far.pfm local_far.pfm ||
        fail "local session frames differ"
    mpi 3 "${flags[@]}" --frames sessions:far.json,near.json --mpi -o "mpi_%d.pfm" > log.txt 2>&1 ||
        { cat log.txt; fail "sessions over 3 ranks"; }
    cmp single_far.pfm mpi_0.pfm && cmp single_near.pfm mpi_1.pfm ||
        fail "session frames over 3 ranks differ"
    echo "ok: 2 session frames (40x30 and 56x24) identical to single renders" ;;
adaptive_frames)
    # Adaptive sampling and an error target are allowed for whole frames: each frame is
    # bitwise the single-process adaptive render, for every split. A minimum below --spp 5
    # lets the allocation pick pixels (below it every pixel samples, as without adaptivity).
    views
    for stop in "--error 0.25 --adaptive-min-spp 2" "--adaptive --adaptive-min-spp 2"; do
        tag=${stop// /}
        for v in front top; do
            "$kdtrace" "${common[@]}" $stop --views views.json --view "$v" -o "single_${tag}_$v.pfm" \
                > /dev/null || fail "single $stop render of $v"
        done
        for n in 2 3; do
            rm -f mpi_*.pfm
            mpi "$n" "${common[@]}" $stop --views views.json --frames views:front,top --mpi \
                -o mpi.pfm > "log_$n.txt" 2>&1 || { cat "log_$n.txt"; fail "$stop over $n ranks"; }
            cmp "single_${tag}_front.pfm" mpi_front.pfm && cmp "single_${tag}_top.pfm" mpi_top.pfm ||
                fail "$stop frames over $n ranks differ from the single renders"
        done
    done
    # The adaptive render is not the fixed-spp one (so the comparisons above can fail).
    "$kdtrace" "${common[@]}" --views views.json --view front -o fixed_front.pfm > /dev/null
    cmp -s fixed_front.pfm single_--error0.25--adaptive-min-spp2_front.pfm &&
        fail "--error made no difference"
    echo "ok: --error and --adaptive frames identical over 2 and 3 ranks" ;;
bad_list)
    # A bad listed file stops every rank before any frame renders: one message naming it,
    # exit status non-zero, no image, no hang (mpi() gives up after 100 s).
    sessions
    views
    echo '{"stop": {"spp": 2}, "trace": {"no_such_key": 1}}' > broken.json
    check() {  # WHAT EXPECTED-REGEX ARGS...
        local what=$1 expect=$2 out rc
        shift 2
        rm -f out_*.pfm
        out=$(mpi 3 "${common[@]}" "$@" --mpi -o "out_%d.pfm" 2>&1); rc=$?
        echo "$out"
        [ $rc -ne 0 ] || fail "$what: exit status 0"
        [ "$(grep -c 'kdtrace: error:' <<< "$out")" -eq 1 ] || fail "$what: not exactly one error message"
        grep -q "kdtrace: error: all 3 ranks failed to start: $expect" <<< "$out" || fail "$what: message"
        ls out_*.pfm 2> /dev/null && fail "$what: a frame was written"
        return 0
    }
    check "missing session" ".*missing.json" --frames sessions:near.json,missing.json
    check "bad key" ".*broken.json.*no_such_key.*unknown key" --frames sessions:near.json,broken.json
    check "unknown view" ".*views.json.*no view named \"back\" (views: front, side, top)" \
        --views views.json --frames views:front,back
    check "missing views file" ".*nope.json" --views nope.json --frames views:all
    # Two frames that would overwrite one file.
    out=$("$kdtrace" "${common[@]}" --frames sessions:near.json,sub/near.json -o o.pfm 2>&1)
    grep -q "would both be written to o_near.pfm" <<< "$out" || { echo "$out"; fail "same output"; }
    echo "ok: bad listed files stop every rank with one message" ;;
stats_output)
    # --mpi-stats is checked with the image before anything loads: never an input, the
    # image, a directory, a device or a file in a missing directory; an empty name is an error.
    cp "$model" model.ply
    sum=$(md5sum < model.ply)
    ln -sf model.ply link.json
    for bad in model.ply link.json x.pfm "$work" /dev/full /nonexistent/s.json ""; do
        rm -f x.pfm
        out=$(mpi 2 render model.ply --no-cache --width 24 --height 16 --spp 1 --threads 1 --quiet \
            --mpi --mpi-stats "$bad" -o x.pfm 2>&1); rc=$?
        echo "$out"
        [ $rc -ne 0 ] || fail "--mpi-stats '$bad': exit status 0"
        grep -q "kdtrace: error: .*--mpi-stats" <<< "$out" || fail "--mpi-stats '$bad': no message"
        [ -e x.pfm ] && fail "--mpi-stats '$bad': the image was written"
    done
    [ "$(md5sum < model.ply)" = "$sum" ] || fail "the model was overwritten"
    # A file the options come from is an input too.
    printf '{"trace":{"seed":3}}\n' > session.png
    out=$(mpi 2 render model.ply --no-cache --session session.png --spp 1 --quiet --mpi \
        -o ./session.png 2>&1)
    grep -q "kdtrace: error: .*cannot write the image: it is the input" <<< "$out" ||
        { echo "$out"; fail "--session file as the image"; }
    [ "$(cat session.png)" = '{"trace":{"seed":3}}' ] || fail "the session file was overwritten"
    mpi 2 render model.ply --no-cache --width 24 --height 16 --spp 1 --threads 1 --quiet --mpi \
        --mpi-stats stats.json -o x.pfm > log.txt 2>&1 || { cat log.txt; fail "a good --mpi-stats"; }
    grep -q '"per_rank"' stats.json || fail "stats.json has no per_rank"
    ls stats.json.*tmp 2> /dev/null && fail "a temporary file was left"
    echo "ok: bad --mpi-stats files refused before the render" ;;
rescue)
    # Rank 0's final write fails (a test fault: the writes go to a missing directory after
    # the checks): the image is saved as $TMPDIR/kdtrace-rescued-PID-NAME, as without --mpi.
    "$kdtrace" "${common[@]}" -o ref.pfm > /dev/null || fail "single-process render"
    rm -rf tmp && mkdir tmp
    out=$(TMPDIR=$work/tmp mpi 2 "${common[@]}" --mpi --mpi-inject 0:write -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -eq 1 ] || fail "exit status $rc, not 1"
    grep -q "kdtrace: error: .*x.pfm.*; the image was saved to $work/tmp/kdtrace-rescued-[0-9]*-x.pfm instead" \
        <<< "$out" || fail "no rescue message"
    cmp ref.pfm tmp/kdtrace-rescued-*-x.pfm || fail "the rescued image differs"
    echo "ok: the image of a failed write is rescued" ;;
test_flags)
    # The test-only flags name a rank of the job and a known fault, or are errors.
    for flags in "--throttle 5:2" "--throttle -1:2" "--mpi-inject 7:load" "--mpi-inject 1:foo" \
        "--mpi-inject 1:write" "--mpi-inject 0:stop" "--mpi-inject 0:interrupt" \
        "--mpi-inject 0:result-item" "--mpi-inject 0:work-bytes" "--mpi-inject 0:options-short"; do
        out=$(mpi 3 "${common[@]}" --mpi $flags -o x.pfm 2>&1); rc=$?
        echo "$out"
        [ $rc -ne 0 ] || fail "$flags: exit status 0"
        grep -q "kdtrace: error: all 3 ranks failed to start: ${flags%% *} " <<< "$out" ||
            fail "$flags: no message"
    done
    echo "ok: bad test flags refused" ;;
interrupt)
    # Ctrl-C or kill to mpirun: it sends every rank SIGCONT, SIGTERM 1 s later and SIGKILL 1 s
    # after that. Rank 0 says once what was kept, no rank hangs, no temporary file is left;
    # mpirun itself exits with 1 (or the signal's status, below). The signal is sent once rank 0 has loaded (its cache line,
    # or the first frame file), when the ranks handle it, whatever the timing after that.
    # KILL_AFTER: seconds from mpirun's SIGTERM to its SIGKILL (1 by default; more, as on a
    # loaded machine, outlasts the 2 s a worker waits before it reports a signal as its own,
    # and the workers must still stay quiet, since rank 0 is gone).
    interrupted() {  # SIGNAL KILL_AFTER READY-COMMAND ARGS...: runs the render, signals mpirun when ready
        local sig=$1 kill_after=$2 ready=$3 pid launcher i
        shift 3
        OMPI_MCA_odls_base_sigkill_timeout=$kill_after "$mpiexec" --oversubscribe \
            --allow-run-as-root -np 3 "$kdtrace" "$@" > log.txt 2>&1 &
        launcher=$!
        for i in $(seq 600); do eval "$ready" && break; sleep 0.1; done
        eval "$ready" || { kill -KILL $launcher; cat log.txt; fail "$sig: the render never got going"; }
        kill -"$sig" $launcher
        # A hang is a failure: mpirun must be gone well before this.
        for i in $(seq 300); do kill -0 $launcher 2> /dev/null || break; sleep 0.1; done
        kill -0 $launcher 2> /dev/null && { kill -KILL $launcher; fail "$sig: mpirun still running 30 s later"; }
        wait $launcher
    }
    big=(render "$model" --cache-dir cache --threads 1 --mpi)
    for sig in INT TERM; do
        rm -rf cache tiles.pfm* && mkdir cache
        interrupted $sig $([ $sig = INT ] && echo 4 || echo 1) "grep -q 'kd-tree cache:' log.txt" \
            "${big[@]}" --width 200 --height 150 \
            --spp 60000 -o tiles.pfm; rc=$?
        cat log.txt
        # mpirun (Open MPI 4.1) ends with 1 after forwarding the signal, or now and then dies
        # of it itself (128 + its number); kdtrace's part is the message and the files.
        [ $rc -eq 1 ] || [ $rc -eq $((128 + $(kill -l $sig))) ] ||
            fail "tiles, SIG$sig: exit status $rc, not 1 or $((128 + $(kill -l $sig)))"
        [ "$(grep -c '^kdtrace: ' log.txt)" -eq 2 ] || fail "tiles, SIG$sig: not the cache line and one message"
        grep -q "^kdtrace: interrupted (SIGTERM); nothing was kept: a tiled --mpi render writes its image only once every tile is back$" \
            log.txt || fail "tiles, SIG$sig: no message"
        ls tiles.pfm* 2> /dev/null && fail "tiles, SIG$sig: a file was left"
    done
    # A sequence writes each frame as it comes: those are kept, and counted.
    rm -rf cache frames && mkdir cache frames
    interrupted INT 1 "ls frames/f_000.pfm > /dev/null 2>&1" "${big[@]}" --width 48 --height 32 \
        --spp 64 --quiet --frames 1000 --turntable -o "frames/f_%03d.pfm"; rc=$?
    cat log.txt
    [ $rc -eq 1 ] || [ $rc -eq 130 ] || fail "frames: exit status $rc, not 1 or 130"
    [ "$(grep -c '^kdtrace: ' log.txt)" -eq 1 ] || fail "frames: not exactly one message"
    n=$(ls frames | wc -l)
    grep -q "^kdtrace: interrupted (SIGTERM); kept the $n of 1000 frames already written$" log.txt ||
        fail "frames: the message does not count the $n frames written"
    ls frames | grep -v '^f_[0-9][0-9][0-9]\.pfm$' && fail "frames: a temporary file was left"
    echo "ok: an interrupted run says what it kept ($n frames) and ends" ;;
frames_session)
    # A farmed frame is its own session, as a local one: `render --session FRAME` (one
    # process) renders it again bit for bit, with its turn of the turntable or its view.
    views
    for run in "t_%d:--frames 4 --turntable" "v:--views views.json --frames views:front,top"; do
        pattern=${run%%:*} flags=${run#*:}
        "$kdtrace" "${common[@]}" $flags -o "$pattern.pfm" > /dev/null || fail "local $flags"
        rm -f "${pattern%%[%_]*}"_*.png
        mpi 3 "${common[@]}" $flags --mpi -o "$pattern.png" > log.txt 2>&1 ||
            { cat log.txt; fail "$flags over 3 ranks"; }
        for png in "${pattern%%[%_]*}"_*.png; do
            "$kdtrace" render --session "$png" --quiet -o "s_${png%.png}.pfm" > /dev/null ||
                fail "$png: session"
            cmp "${png%.png}.pfm" "s_${png%.png}.pfm" || fail "render --session $png differs"
        done
    done
    echo "ok: farmed frames render again through --session" ;;
frames_passes)
    # A farmed frame carries kdtrace:passes as the frame rendered without --mpi does, with the
    # same value: explicit passes (1 + 2 + 2 for --spp 5 --spp-per-pass 2), automatic ones
    # (1 + 16 + 16 + 7 for --spp 40) and adaptive ones (run_render's count). The frames are
    # small, so no automatic pass meets its one-second bound and the local counts are fixed.
    views
    passes_of() { "$kdtrace" info "$1" | sed -n 's/^kdtrace:passes: //p'; }
    for run in "explicit:--spp 5 --spp-per-pass 2:3" "auto:--spp 40:4" \
        "adaptive:--spp 8 --error 0.3 --adaptive-min-spp 2:"; do
        tag=${run%%:*} rest=${run#*:}
        flags=${rest%:*} expect=${rest##*:}
        args=(render "$model" --no-cache --width 24 --height 16 --threads 1 --quiet $flags
              --views views.json --frames views:front,top)
        rm -f "l_$tag"_*.png "m_$tag"_*.png
        "$kdtrace" "${args[@]}" -o "l_$tag.png" > /dev/null || fail "$tag: local frames"
        mpi 2 "${args[@]}" --mpi --distribution strips -o "m_$tag.png" > log.txt 2>&1 ||
            { cat log.txt; fail "$tag: frames over 2 ranks"; }
        for v in front top; do
            l=$(passes_of "l_${tag}_$v.png") m=$(passes_of "m_${tag}_$v.png")
            [ -n "$l" ] || fail "$tag, $v: the local frame has no kdtrace:passes"
            [ -z "$expect" ] || [ "$l" = "$expect" ] || fail "$tag, $v: $l local passes, not $expect"
            [ "$m" = "$l" ] || fail "$tag, $v: kdtrace:passes '$m' over 2 ranks, '$l' without --mpi"
        done
    done
    echo "ok: farmed frames carry the local frames' kdtrace:passes" ;;
interrupt_worker)
    # A worker signalled while its result is on the way (--mpi-inject 1:interrupt: rank 1
    # raises SIGTERM just after sending its first frame and leaves the farm; the memory it
    # frees then is overwritten). Under strips rank 0 renders the small frame and rank 1 the
    # big one; rank 0 then sleeps 99x its render time without receiving (--throttle), so
    # rank 1's frame most likely arrives while rank 0 sleeps, and is received after rank 1
    # has left the farm. Rank 0 must still receive that frame intact (or name rank 1 if it
    # cannot): never garbage. Rank 1 says it was interrupted, then mpirun ends the job and rank
    # 0 says what it kept; every frame written is the local render's.
    camera='"camera": {"eye": [1.5, 1.2, 3.0], "target": [0, 0.7, 0], "up": [0, 1, 0], "vfov_degrees": 35}'
    echo "{\"scene\": {\"width\": 16, \"height\": 16, $camera}}" > small.json
    echo "{\"scene\": {\"width\": 96, \"height\": 64, $camera}}" > big.json
    args=(render "$model" --no-cache --spp 5 --spp-per-pass 2 --seed 11 --threads 1 --quiet
          --frames sessions:small.json,big.json)
    "$kdtrace" "${args[@]}" -o local.pfm > /dev/null || fail "local frames"
    rm -rf frames && mkdir frames
    mpi 2 "${args[@]}" --mpi --distribution strips --mpi-inject 1:interrupt --throttle 0:100 \
        -o frames/f.pfm > log.txt 2>&1; rc=$?
    cat log.txt
    [ $rc -eq 143 ] || fail "exit status $rc, not 143 (SIGTERM)"
    grep -q "^kdtrace: rank 1: interrupted (SIGTERM); ending this rank$" log.txt ||
        fail "rank 1 does not say it was interrupted"
    grep -q "^kdtrace: interrupted (SIGTERM); all 2 frames were written$" log.txt ||
        fail "rank 0 does not say it kept both frames"
    grep -q "error" log.txt && fail "an error"
    for f in small big; do cmp "frames/f_$f.pfm" "local_$f.pfm" || fail "frame $f differs"; done
    echo "ok: a worker interrupted with a send pending does not corrupt rank 0's results" ;;
worker_warnings)
    # A worker's load lines reach the terminal through rank 0, once per text with the ranks
    # that said them: here ranks 1 and 2 run where --cache-dir c is a file, not a directory.
    rm -rf a b && mkdir -p a/c b && touch b/c
    args=(render "$model" --width 16 --height 8 --spp 1 --threads 1 --mpi -o "$work/x.pfm")
    out=$(timeout -k 5 100 "$mpiexec" --oversubscribe --allow-run-as-root \
        -np 1 -wdir "$work/a" "$kdtrace" "${args[@]}" --cache-dir c : \
        -np 2 -wdir "$work/b" "$kdtrace" "${args[@]}" --cache-dir c 2>&1) ||
        { echo "$out"; fail "the run failed"; }
    echo "$out"
    [ "$(grep -c 'cannot write to c' <<< "$out")" -eq 1 ] || fail "the workers' warning is not printed once"
    grep -q "^kdtrace: ranks 1, 2 of 3: warning: kd-tree cache: cannot write to c: not a writable directory; tree not cached$" \
        <<< "$out" || fail "the workers' warning does not name them"
    # Which rank wrote a cache file and which loaded one is no news: here rank 0 loads what
    # it wrote above and the workers write their own; rank 0's line alone is printed.
    rm -rf d && mkdir -p d/c
    out=$(timeout -k 5 100 "$mpiexec" --oversubscribe --allow-run-as-root \
        -np 1 -wdir "$work/a" "$kdtrace" "${args[@]}" --cache-dir c : \
        -np 2 -wdir "$work/d" "$kdtrace" "${args[@]}" --cache-dir c 2>&1) ||
        { echo "$out"; fail "the run with caches of its own failed"; }
    echo "$out"
    ls d/c/*.kdt > /dev/null || fail "the workers wrote no cache"
    [ "$(grep -c '^kdtrace: ' <<< "$out")" -eq 1 ] || fail "the workers' cache writes were printed"
    # Lines every rank says alike (the cache loaded, with other times) come from rank 0 alone.
    out=$(mpi 3 "${args[@]}" --cache-dir a/c 2>&1) || { echo "$out"; fail "the cached run failed"; }
    echo "$out"
    [ "$(grep -c '^kdtrace: ' <<< "$out")" -eq 1 ] || fail "the cached run printed more than rank 0's line"
    echo "ok: workers' warnings printed by rank 0" ;;
option_error)
    # Every rank parses the same command line: an error or a warning found before MPI starts
    # is printed once, by rank 0, and every rank exits with its status.
    for flags in "--tile-batch -1:--tile-batch must be in" "--no-such-flag:--no-such-flag" \
        "--distribution bogus:--distribution must be one of"; do
        out=$(mpi 3 "${common[@]}" --mpi ${flags%%:*} -o x.pfm 2>&1); rc=$?
        echo "$out"
        [ $rc -ne 0 ] || fail "${flags%%:*}: exit status 0"
        [ "$(grep -c -- "${flags#*:}" <<< "$out")" -eq 1 ] || fail "${flags%%:*}: not printed once"
    done
    out=$(mpi 3 "${common[@]}" --mpi --max-spp 4 -o x.pfm 2>&1) || { echo "$out"; fail "warning run"; }
    echo "$out"
    [ "$(grep -c 'warning: --spp 5 is above --max-spp 4' <<< "$out")" -eq 1 ] || fail "warning not printed once"
    echo "ok: option errors and warnings printed by rank 0 alone" ;;
bench_quote)
    # bench mpi launches without a shell: a quote in a name works and a crafted name runs
    # nothing.
    rm -rf q && mkdir q && cp "$model" "q/it's.ply" && cp "$model" "q/x'; touch pwned; echo '.ply"
    for m in "it's.ply" "x'; touch pwned; echo '.ply"; do
        out=$(cd q && timeout -k 5 100 "$kdtrace" bench mpi --model "$work/q/$m" --mpiexec "$mpiexec" \
            --ranks 1 --width 24 --height 16 --spp 1 --repeat 1 --work-dir "$work/q/w d'q" 2>&1)
        rc=$?
        echo "$out"
        [ $rc -eq 0 ] || fail "bench mpi with the model '$m': exit status $rc"
    done
    [ -e q/pwned ] || [ -e pwned ] && fail "a file name ran a command"
    out=$(timeout 100 "$kdtrace" bench mpi --model "$model" --mpiexec /bin/false --ranks 1 \
        --width 24 --height 16 --spp 1 --repeat 1 --work-dir "$work/q/f" 2>&1)
    grep -q "bench mpi: '/bin/false' .* failed; see" <<< "$out" || { echo "$out"; fail "/bin/false"; }
    echo "ok: bench mpi passes file names as they are" ;;
bench_no_baseline)
    # Speedups compare with the 1-rank run of the same work: without one they are "-" and
    # the turntable line names no ideal time; with one (given last) they are numbers.
    bench=(bench mpi --model "$model" --mpiexec "$mpiexec" --no-tiles --frames 2 --repeat 1
           --width 24 --height 16 --spp 1 --work-dir "$work/b")
    out=$(timeout -k 5 100 "$kdtrace" "${bench[@]}" --ranks 3 2>&1) || { echo "$out"; fail "--ranks 3"; }
    echo "$out"
    grep -q '^| 2 frames | dynamic | 3 | no | [^|]* | [^|]* | - | - | - | ' <<< "$out" ||
        fail "--ranks 3: speedup, speedup / ranks and cpu eff. are not -"
    grep -q '^turntable, 3 ranks: [0-9.]* s (no 1-rank run to compare with); ' <<< "$out" ||
        fail "--ranks 3: the turntable line"
    out=$(timeout -k 5 100 "$kdtrace" "${bench[@]}" --ranks 3,1 2>&1) || { echo "$out"; fail "--ranks 3,1"; }
    echo "$out"
    grep -q '^| 2 frames | dynamic | 3 | no | [^|]* | [^|]* | [0-9.]* | [0-9.]* | [0-9.]* | ' <<< "$out" ||
        fail "--ranks 3,1: no speedup against the 1-rank run"
    grep -q '^turntable, 3 ranks: [0-9.]* s against the ideal [0-9.]* s (1 rank / 3): [0-9.]*x; ' <<< "$out" ||
        fail "--ranks 3,1: the turntable line"
    echo "ok: bench mpi without a 1-rank run prints no speedup" ;;
frames_names)
    # Each frame written is named, as without --mpi; the summary counts the frames.
    views
    out=$(mpi 2 render "$model" --no-cache --width 16 --height 8 --spp 1 --threads 1 \
        --views views.json --frames views:all --mpi -o "$work/d.pfm" 2>&1) ||
        { echo "$out"; fail "the run failed"; }
    echo "$out"
    for v in front side top; do
        grep -q "^kdtrace: frame [1-3]/3 -> $work/d_$v.pfm$" <<< "$out" || fail "frame $v not named"
        [ -s "d_$v.pfm" ] || fail "d_$v.pfm not written"
    done
    grep -q "^render: [^:]*: 3 frames, " <<< "$out" || fail "the summary does not count the frames"
    echo "ok: the frames are named" ;;
threads_default)
    # Without --threads each rank takes its share of the node's cores, not all of them (ranks x
    # cores threads spin-waiting at every pass's end); the image is the same. Unbound, so
    # that every rank sees every core.
    "$kdtrace" "${common[@]}" -o ref.pfm > /dev/null || fail "single-process render"
    args=(render "$model" --no-cache --width 72 --height 40 --spp 5 --spp-per-pass 2 --seed 11)
    out=$(timeout -k 5 100 "$mpiexec" --oversubscribe --allow-run-as-root --bind-to none -np 3 \
        "$kdtrace" "${args[@]}" --mpi -o mpi.pfm 2>&1) || { echo "$out"; fail "the run failed"; }
    echo "$out"
    cores=$(nproc)
    each=$((cores / 3 > 0 ? cores / 3 : 1))
    grep -q "^kdtrace: --mpi: 3 ranks on this node's $cores cores: $each threads\? each" <<< "$out" ||
        fail "no share of the cores"
    cmp ref.pfm mpi.pfm || fail "the image differs"
    out=$(timeout -k 5 100 "$mpiexec" --oversubscribe --allow-run-as-root --bind-to none -np 3 \
        "$kdtrace" "${args[@]}" --threads 1 --mpi -o mpi.pfm 2>&1) || { echo "$out"; fail "--threads 1"; }
    grep -q "^kdtrace: --mpi:" <<< "$out" && fail "--threads given, and still shared"
    echo "ok: the ranks share the cores" ;;
camera_errors)
    # A camera error reads as a single render's under --frames and --mpi (after --mpi's "all N
    # ranks failed to ...: "): the flags named with their values, the other parts by source.
    echo '{"scene": {"eye": [1, 2, 3]}}' > eye.json
    echo '{"scene": {"target": [1, 2, 3]}}' > target.json
    small=(render "$model" --no-cache --width 8 --height 6 --spp 1 --threads 1 --quiet)
    for flags in "--target 1,2,3 --session eye.json" "--up 0,0,0 --session target.json" \
        "--eye 1,1,1 --target 1,1,1" "--up 0,0,0"; do
        read -ra f <<< "$flags"
        one=$("$kdtrace" "${small[@]}" "${f[@]}" -o one.pfm 2>&1) && fail "$flags: exit status 0"
        echo "$one"
        msg=${one#kdtrace: error: }
        [ "$msg" != "$one" ] && [ "$(wc -l <<< "$one")" -eq 1 ] || fail "$flags: not one error"
        [[ $msg == *"${f[0]} ${f[1]}"* ]] || fail "$flags: the flag's value is not named"
        out=$("$kdtrace" "${small[@]}" "${f[@]}" --frames 2 --turntable -o f%d.pfm 2>&1) &&
            fail "$flags --frames: exit status 0"
        [ "$out" = "$one" ] || { echo "$out"; fail "$flags --frames: another message"; }
        out=$(mpi 2 "${small[@]}" "${f[@]}" --mpi -o m.pfm 2>&1) && fail "$flags --mpi: exit status 0"
        line=$(grep '^kdtrace: error: ' <<< "$out")
        [ "$(sed -E 's/^kdtrace: error: all 2 ranks failed to [^:]*: /kdtrace: error: /' <<< "$line")" = "$one" ] ||
            { echo "$out"; fail "$flags --mpi: another message"; }
    done
    echo "ok: camera errors read alike with --frames and --mpi" ;;
*) fail "unknown case $case_name" ;;
esac
