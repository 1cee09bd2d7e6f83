#!/bin/bash
# Every long option that some `kdtrace ... --help` lists is mentioned in docs/usage.md as
# `--name` (not as the prefix of a longer option). The commands are read from `kdtrace --help`
# and `kdtrace bench --help`, so a command added later is checked too and one built without
# (the viewer) is not. Usage: options_documented_test.sh KDTRACE USAGE_MD.
set -u
kdt=$1 doc=$2
fail() { echo "FAIL: $*"; exit 1; }
[ -r "$doc" ] || fail "cannot read $doc"
# subcommands HELP_TEXT: the names under its "Subcommands:" heading.
subcommands() { sed -n '/^Subcommands:/,$p' <<<"$1" | sed -n 's/^  \([a-z][a-z0-9-]*\) .*/\1/p'; }
# long_options HELP_TEXT: the long names of its option lines ("  -o,--output TEXT ...",
# "  --tiles,--no-tiles{false}"), not the options a description mentions.
long_options() {
    sed -n '/^Options:/,/^Subcommands:/p' <<<"$1" | grep -E '^  +-' |
        sed -E 's/^ +//; s/[ {].*//' | tr ',' '\n' | grep -E '^--[a-z0-9]' | grep -vxF -- '--help'
}
top=$("$kdt" --help) || fail "kdtrace --help failed"
commands=()
for c in $(subcommands "$top"); do
    help=$("$kdt" $c --help) || fail "kdtrace $c --help failed"
    subs=$(subcommands "$help")
    if [ -n "$subs" ]; then
        for s in $subs; do commands+=("$c $s"); done
    else
        commands+=("$c")
    fi
done
[ ${#commands[@]} -ge 5 ] || fail "found only ${#commands[@]} commands in kdtrace --help"
missing=0 checked=0
for c in "${commands[@]}"; do
    help=$("$kdt" $c --help) || fail "kdtrace $c --help failed"
    for o in $(long_options "$help"); do
        checked=$((checked + 1))
        if ! grep -qE -- "(^|[^a-z0-9-])$o([^a-z0-9-]|$)" "$doc"; then
            echo "undocumented: kdtrace $c $o (not in $doc)"
            missing=$((missing + 1))
        fi
    done
done
[ $checked -ge 50 ] || fail "found only $checked options in ${#commands[@]} commands' --help"
[ $missing -eq 0 ] || fail "$missing of $checked options are not in $doc"
echo "PASS: all $checked options of ${#commands[@]} commands are in $doc"
