#!/usr/bin/env bash
# One command from a fresh Debian machine to a rendered image you can look at: installs
# only the packages the `aliquot` binary's build needs, builds that one target, and renders
# the built-in Cornell box in-process (no servers) to an EXR and a PNG beside it.
# The tests, benchmarks and the dashboard are not built here: scripts/test.sh installs
# and builds everything. A step that fails stops the script with the step's name.
set -euo pipefail
cd "$(dirname "$0")/.."

step() {
    local name=$1 start=$SECONDS status
    shift
    echo "demo.sh: $name" >&2
    "$@" || {
        status=$?
        echo "demo.sh: step '$name' failed (exit status $status); nothing after it ran" >&2
        exit 1
    }
    echo "demo.sh: $name took $((SECONDS - start)) s" >&2
}

step "install the build packages (scripts/install-deps.sh --demo)" \
    bash scripts/install-deps.sh --demo
# The configuration of scripts/build.sh, so that a later build.sh or test.sh reuses build/
# and only adds what the demo skipped, with the rooms compiled as unity builds (batches of
# files in one translation unit: about a third less compiling, cmake/rooms.cmake). The
# option stays in build/'s cache; it changes how the libraries compile, not what they do.
configure() {
    cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DALIQUOT_UNITY_ROOMS=ON >/dev/null
}
step "configure (cmake)" configure
build() {
    cmake --build build --target aliquot --parallel "$(nproc)" && return 0
    # A unity batch fails where its files compile alone when two files of a room repeat a
    # name in their anonymous namespaces (cmake/rooms.cmake lists those known): the
    # compiler's error is above; the build goes on file by file.
    echo "demo.sh: the unity build failed; building file by file" >&2
    cmake -S . -B build -DALIQUOT_UNITY_ROOMS=OFF >/dev/null &&
        cmake --build build --target aliquot --parallel "$(nproc)"
}
step "build the aliquot binary" build
mkdir -p out
step "render the Cornell box" \
    build/bin/aliquot render --scene cornell-box --resolution 256x256 --spp 256 --seed 1 \
    --out out/cornell-box.exr --png
echo "output: out/cornell-box.exr (linear, 32-bit float) and out/cornell-box.png (sRGB," \
    "open it in any image viewer)"
echo "next: build/bin/aliquot render --help; compare two images with" \
    "build/bin/aliquot compare A.exr B.exr"
