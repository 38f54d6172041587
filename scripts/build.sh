#!/usr/bin/env bash
# Configures and builds everything (Release) into build/; build/bin/aliquot is the binary.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build --parallel "$(nproc)"
