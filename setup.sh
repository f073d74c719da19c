#!/usr/bin/env bash
# Penumbra setup. Two commands, on a fresh Debian 12 machine:
#   ./setup.sh        install missing packages, build, render the built-in demo scene to demo.png
#                     and the comparison strip demo-compare.png (sm | srt | srt with the traced pixels red)
#   ./setup.sh test   install missing packages, build, run the whole test suite with ctest
set -euo pipefail
cd "$(dirname "$0")"

mode="${1:-demo}"
build_dir="${PENUMBRA_BUILD_DIR:-build}"
jobs="$(nproc)"

packages=(
  build-essential cmake pkg-config
  libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers glslang-tools
  libmeshoptimizer-dev libdraco-dev libeigen3-dev libtinygltf-dev
  libglm-dev libopenimageio-dev nlohmann-json3-dev libcli11-dev libxxhash-dev libembree-dev
  libgtest-dev clang libclang-rt-14-dev
  pybind11-dev python3-dev python3-numpy
  gnuplot-nox
  strace
)

missing=()
for package in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=()
  if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release
cmake --build "$build_dir" -j "$jobs"

case "$mode" in
  demo)
    "$build_dir/penumbra" render -o demo.png --size 1024 --shadows srt --compare demo-compare.png
    echo "setup: wrote $(pwd)/demo.png and $(pwd)/demo-compare.png (sm | srt | traced pixels in red)"
    ;;
  test)
    ctest --test-dir "$build_dir" --output-on-failure -j "$jobs" --timeout 600
    ;;
  *)
    echo "usage: ./setup.sh [demo|test]" >&2
    exit 2
    ;;
esac
