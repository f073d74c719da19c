#!/bin/bash
# Packs Penumbra for a Linux GPU machine that cannot install packages: builds
# without OpenImageIO (PENUMBRA_WITH_OPENIMAGEIO=OFF: PNG output only) into
# build-device/, then writes DIR/bundle.tar.xz (the binaries, every library
# they load except glibc's and libstdc++, libglvnd for NVIDIA's Vulkan driver,
# the Vulkan validation layer) and DIR/run.sh, which unpacks it there at the
# same absolute paths (the tests' scratch folder is compiled in) and runs the
# benchmark suite (hard, point lights with rh's variants, soft) and the runtime
# tests with validation, each step under a limit (HARD_LIMIT, POINT_LIMIT,
# TESTS_LIMIT, SOFT_LIMIT seconds).
#
#   bench/device_bundle.sh DIR            (here; BUILD=folder to build elsewhere)
#   bash DIR/run.sh [OUT]                 (there, in a copy of the repository root)
#
# The README ("On an NVIDIA H200") has what such a run found.
set -euo pipefail
dir=${1:?usage: bench/device_bundle.sh DIR}
root=$(cd "$(dirname "$0")/.." && pwd)
build=$(realpath -m "${BUILD:-$root/build-device}") # BUILD: another build folder
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DPENUMBRA_WITH_OPENIMAGEIO=OFF -DPENUMBRA_BUILD_PYTHON=OFF \
      -DPENUMBRA_BUILD_FUZZ=OFF > /dev/null
cmake --build "$build" -j"$(nproc)" --target penumbra runtime_tests
mkdir -p "$dir" "$build/device/lib" "$build/device/layer" "$build/tests/tmp"
lib=/usr/lib/x86_64-linux-gnu
layer=$lib/libVkLayer_khronos_validation.so
[ -f "$layer" ] || { echo "device_bundle.sh: $layer missing (Debian: vulkan-validationlayers)" >&2; exit 1; }
# Libraries: everything the binaries and the layer load, less the C and C++ runtimes the target has (newer).
ldd "$build/penumbra" "$build/tests/runtime_tests" "$layer" | awk '$3 ~ /^\// {print $3}' | sort -u |
    grep -v -E '/(libc|libm|libdl|libpthread|librt|libstdc\+\+|libgcc_s|ld-linux[^/]*)\.so' | xargs -I{} cp -L {} "$build/device/lib/"
for f in libGLdispatch.so.0 libGLX.so.0 libEGL.so.1 libOpenGL.so.0 libGL.so.1; do # NVIDIA's ICD (libGLX_nvidia) needs libglvnd
    [ -e "$lib/$f" ] && cp -L "$lib/$f" "$build/device/lib/"
done
cp "$layer" "$build/device/layer/"
sed "s#\"library_path\": *\"[^\"]*\"#\"library_path\": \"$build/device/layer/libVkLayer_khronos_validation.so\"#" \
    /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json > "$build/device/layer/VkLayer_khronos_validation.json"
tar -cJf "$dir/bundle.tar.xz" -C / "${build#/}/penumbra" "${build#/}/tests/runtime_tests" "${build#/}/device" \
    --no-recursion "${build#/}/tests/tmp" # the tests' scratch folder, empty
cat > "$dir/run.sh" <<RUN
#!/bin/bash
# Made by bench/device_bundle.sh: unpack, then tests and benchmarks, each under a time limit; results in OUT.
set -u
out=\${1:-\${OUT:-device-results}}; mkdir -p "\$out"
here=\$(cd "\$(dirname "\$0")" && pwd)
tar -xJf "\$here/bundle.tar.xz" -C / || { echo "run.sh: cannot unpack the bundle" >&2; exit 1; }
export LD_LIBRARY_PATH=$build/device/lib VK_LAYER_PATH=$build/device/layer
P=$build/penumbra
{ nvidia-smi 2>&1 | head -12; uname -a; nproc; } > "\$out/env.txt"
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json # NVIDIA's, where the loader does not look by default
if ! \$P devices 2>/dev/null | grep -q -v -i llvmpipe && [ -f \$icd ]; then
    export VK_DRIVER_FILES=\$icd VK_ICD_FILENAMES=\$icd
fi
\$P devices >> "\$out/env.txt" 2>&1 || { cat "\$out/env.txt"; exit 1; }
cd /tmp
step() { local name=\$1 limit=\$2; shift 2; local s=\$(date +%s); timeout "\$limit" "\$@" > "\$out/\$name.log" 2>&1
         echo "\$name rc=\$? \$((\$(date +%s) - s)) s" | tee -a "\$out/steps.txt"; }
# Most wanted first: a lease can end before the last step. The tar is rewritten after each bench step.
bench() { local name=\$1 limit=\$2; shift 2; step \$name \$limit \$P bench full --out /tmp/pb/\$name --size 1024 --no-plots --quiet "\$@"
          tar -cJf "\$out/bench.tar.xz" --exclude='*.png' -C /tmp pb; }
bench hard \${HARD_LIMIT:-120} --frames 20 --sections methods
bench point \${POINT_LIMIT:-120} --frames 10 --methods sm,srt,frt,rh --sections point,rh_variants
step tests \${TESTS_LIMIT:-300} env PENUMBRA_VALIDATION=1 $build/tests/runtime_tests
bench soft \${SOFT_LIMIT:-120} --frames 20 --methods sm,srt,frt --sections soft
grep -E '^\[  FAILED|^\[  PASSED|tests ran' "\$out/tests.log" | tail -12
RUN
chmod +x "$dir/run.sh"
ls -la "$dir"
