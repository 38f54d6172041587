#!/usr/bin/env bash
# Configures and builds everything (Release) into build/; build/bin/aliquot is the binary.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build --parallel "$(nproc)"
# The dashboard the coordinator serves; returns at once when nothing in web/ changed. A
# failure here (no npm, no network for the first install) fails the build, with npm's own
# message above: a coordinator without its dashboard is not a successful build (the C++
# binaries are built by then and usable).
bash web/build.sh
