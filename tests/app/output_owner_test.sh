#!/bin/bash
# An existing output the user may not replace is refused before any work, naming the reason:
# a write-protected file (as `cp` refuses it; root may) and another user's file in a sticky
# directory such as /tmp (the rename into place would fail only after the render). As root the
# commands run as nobody through setpriv; as another user only the write-protected case runs.
# Usage: output_owner_test.sh KDTRACE WORKDIR.
set -u
kdt=$1 dir=$2
rm -rf "$dir" && mkdir -p "$dir" || exit 1
cd "$dir" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cp /usr/share/assimp/models/PLY/cube.ply m.ply
as=()
if [ "$(id -u)" = 0 ]; then
    command -v setpriv >/dev/null || { echo "PASS: output owner (skipped: no setpriv)"; exit 0; }
    as=(setpriv --reuid=65534 --regid=65534 --clear-groups)
fi
export KDT_CACHE_DIR=$dir/cache
render=(render m.ply --width 8 --height 6 --spp 1 --quiet --no-cache)

# refused EXPECTED-MESSAGE FILE: rendering to FILE (as the user under test) must fail with
# that message and leave FILE as it was.
refused() {
    local before
    before=$(md5sum "$2")
    out=$("${as[@]}" "$kdt" "${render[@]}" -o "$2" 2>&1) && fail "accepted: $2"
    grep -q -- "$1" <<<"$out" || fail "$2: expected '$1', got: $out"
    [ "$(md5sum "$2")" = "$before" ] || fail "$2 changed"
    echo "refused: $2 -> $out"
}

mkdir open && chmod 0777 open
printf 'keep\n' >open/ro.png && chmod 0444 open/ro.png
refused "open/ro.png: cannot write the image: the existing file is not writable" open/ro.png
if [ ${#as[@]} -gt 0 ]; then
    mkdir sticky && chmod 1777 sticky
    printf 'keep\n' >sticky/theirs.png  # root's, writable by all: only the sticky bit stops it
    chmod 0666 sticky/theirs.png
    refused "sticky/theirs.png: cannot write the image: it belongs to another user (uid 0) in the sticky directory sticky" sticky/theirs.png
    "${as[@]}" "$kdt" "${render[@]}" -o sticky/mine.png >/dev/null || fail "a new file in sticky"
    "${as[@]}" "$kdt" "${render[@]}" -o sticky/mine.png >/dev/null || fail "own file in sticky"
    # Root replaces a write-protected file, as cp does.
    "$kdt" "${render[@]}" -o open/ro.png >/dev/null || fail "root could not replace open/ro.png"
fi
echo "PASS: output owner"
