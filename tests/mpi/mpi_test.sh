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
    # Rank 1 sleeps 7x its render time. Dynamic gives it fewer tiles than either other rank;
    # the static distributions give it its fixed share whatever its speed.
    big=(render "$model" --no-cache --width 160 --height 128 --spp 8 --threads 1 --quiet
         --throttle 1:8)
    for dist in dynamic strips interleaved; do
        mpi 3 "${big[@]}" --mpi --distribution "$dist" -o "t_$dist.pfm" > "t_$dist.txt" 2>&1 ||
            { cat "t_$dist.txt"; fail "$dist throttled"; }
        cat "t_$dist.txt"
    done
    t0=$(tiles_of t_dynamic.txt 0) t1=$(tiles_of t_dynamic.txt 1) t2=$(tiles_of t_dynamic.txt 2)
    [ "$t1" -lt "$t0" ] && [ "$t1" -lt "$t2" ] ||
        fail "dynamic: throttled rank 1 did $t1 tiles, ranks 0 and 2 did $t0 and $t2"
    # 80 tiles: strips of 10 tile columns give rows 0-2, 3-5, 6-7; interleaved 27, 27, 26.
    [ "$(tiles_of t_strips.txt 1)" -eq 30 ] || fail "strips: rank 1 did not do its 30 tiles"
    [ "$(tiles_of t_interleaved.txt 1)" -eq 27 ] || fail "interleaved: rank 1 did not do 27 tiles"
    cmp t_dynamic.pfm t_strips.pfm && cmp t_dynamic.pfm t_interleaved.pfm ||
        fail "throttled renders differ"
    echo "ok: dynamic gave the throttled rank $t1 tiles (others $t0, $t2)" ;;
fail_load)
    out=$(mpi 3 "${common[@]}" --mpi --mpi-inject 1:load -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a rank that cannot load gave exit status 0"
    [ "$(grep -c 'kdtrace: error:' <<< "$out")" -eq 1 ] || fail "not exactly one error message"
    grep -q "kdtrace: error: rank 1 of 3 could not load the scene: .*kdtrace-injected-fault.*cannot open" <<< "$out" ||
        fail "message does not name rank 1 and the reason" ;;
fail_hash)
    out=$(mpi 3 "${common[@]}" --mpi --mpi-inject 2:hash -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a rank with another tree gave exit status 0"
    grep -q "kdtrace: error: rank 2 of 3 renders a different scene or kd-tree than rank 0" <<< "$out" ||
        fail "message does not name rank 2" ;;
fail_missing)
    out=$(mpi 2 render "$work/no_such_model.ply" --no-cache --spp 1 --mpi -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a missing model gave exit status 0"
    grep -q "kdtrace: error: every rank could not load the scene: .*no_such_model.ply" <<< "$out" ||
        fail "message" ;;
timeout)
    # Rank 2 sleeps 100000x its render time: the run is stuck until --timeout ends it.
    out=$(mpi 3 "${common[@]}" --mpi --throttle 2:100000 --timeout 6 -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "a timed-out run gave exit status 0"
    grep -q "kdtrace: error: --timeout 6 s reached; every rank stopped" <<< "$out" ||
        fail "no timeout message" ;;
refuse_adaptive)
    out=$(mpi 2 "${common[@]}" --error 0.1 --mpi -o x.pfm 2>&1); rc=$?
    echo "$out"
    [ $rc -ne 0 ] || fail "--error with --mpi gave exit status 0"
    grep -q "every rank could not start: a distributed render (--mpi) takes a fixed stop.spp" <<< "$out" ||
        fail "message" ;;
*) fail "unknown case $case_name" ;;
esac
