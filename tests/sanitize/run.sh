#!/usr/bin/env bash
# Builds the suite with sanitizers in its own build folder and runs a subset
# of it; any sanitizer report fails (exit status != 0). ctest runs both modes
# (tests sanitize_asan and sanitize_tsan); by hand:
#   tests/sanitize/run.sh asan [BUILD_DIR]     # ASan + UBSan (default build-asan/)
#   tests/sanitize/run.sh tsan [BUILD_DIR]     # TSan (default build-tsan/)
# Environment: JOBS (build jobs, default nproc), PENUMBRA_SANITIZE_FILTER (a
# gtest filter for runtime_tests instead of the subset below).
set -euo pipefail
mode="${1:?usage: run.sh asan|tsan [BUILD_DIR]}"
source_dir="$(cd "$(dirname "$0")/../.." && pwd)"
here="$source_dir/tests/sanitize"
jobs="${JOBS:-$(nproc)}"

case "$mode" in
  asan) sanitize=address,undefined ;;
  tsan) sanitize=thread ;;
  *) echo "run.sh: mode must be asan or tsan" >&2; exit 2 ;;
esac
build="${2:-$source_dir/build-$mode}"

# -O1: a sanitized -O3 build takes much longer to compile for little gain; asserts stay on.
cmake -S "$source_dir" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
      -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g" -DPENUMBRA_SANITIZE="$sanitize" -DPENUMBRA_BUILD_FUZZ=OFF -DPENUMBRA_BUILD_PYTHON=OFF >/dev/null

# Every report is fatal; leaks are reports. Third-party code that is not ours
# (llvmpipe's JIT, the Vulkan loader and layers, Embree) is suppressed in the
# files beside this script, each entry with its reason.
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:detect_stack_use_after_return=0:strict_string_checks=1:check_initialization_order=1"
export LSAN_OPTIONS="suppressions=$here/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:suppressions=$here/ubsan.supp"
# history_size=7: the longest access history, so that stacks of TBB worker threads are restored
# and the libtbb / libembree3 suppressions can match them.
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:history_size=7:suppressions=$here/tsan.supp:print_suppressions=0"
export PENUMBRA_VALIDATION=1

run() {
  echo "run.sh $mode: $*"
  "$@"
}

if [ "$mode" = asan ]; then
  # Everything of formats and preprocess; of the runtime, the CLI end to end (the sanitized
  # penumbra binary), the injected device faults (error paths), the oracle and the ray
  # tracer's CPU side, the image writer and the frame structure. The raster-only tests
  # (culling paths, soft-shadow sweeps) add minutes and no host code of their own.
  filter="${PENUMBRA_SANITIZE_FILTER:-Cli.*:DeviceFaults.*:Oracle.*:RayTracer.City*:ImageOutput.*:FrameStructure.*:HardShadows.Selective*:AliasFreeShadowMaps.SuiteScenes*}"
  nice -n 15 cmake --build "$build" -j "$jobs" --target formats_tests preprocess_tests runtime_tests penumbra
  run "$build/tests/formats_tests" --gtest_brief=1
  run "$build/tests/preprocess_tests" --gtest_brief=1
  # The Vulkan loader unloads the validation layer with its instance, and the layer leaves
  # allocations behind; LeakSanitizer then cannot name the module to suppress them (and
  # symbolizing them takes minutes per process). Preloaded, the layer stays mapped and
  # lsan.supp names it. The ASan runtime must come first.
  export LD_PRELOAD="$(c++ -print-file-name=libasan.so) libVkLayer_khronos_validation.so"
  # LeakSanitizer cannot run under ptrace: Cli.PreprocessSyncs* (strace) is left out.
  run "$build/tests/runtime_tests" --gtest_brief=1 --gtest_filter="$filter:-Cli.PreprocessSyncs*"
  unset LD_PRELOAD
else
  # The threaded code: the preprocessor (clustering, strips, BVH in parallel), the
  # generators, and the Embree oracle's worker threads.
  filter="${PENUMBRA_SANITIZE_FILTER:-Oracle.*:RayTracer.City*}"
  nice -n 15 cmake --build "$build" -j "$jobs" --target preprocess_tests runtime_tests penumbra
  run "$build/tests/preprocess_tests" --gtest_brief=1
  # Without the validation layer: its own threads race in its own (uninstrumented) code
  # (a queue thread it starts in vkQueueSubmit), which is not ours to fix; the normal suite runs it.
  PENUMBRA_VALIDATION=0 run "$build/tests/runtime_tests" --gtest_brief=1 --gtest_filter="$filter"
fi
echo "run.sh $mode: no sanitizer reports"
