#!/usr/bin/env bash
# One command from a fresh Debian machine to a rendered image: installs what is missing,
# builds, and renders the built-in Cornell box in-process (no servers).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
mkdir -p out
build/bin/aliquot render --scene cornell-box --resolution 256x256 --spp 256 --seed 1 \
    --out out/cornell-box.exr
echo "output: out/cornell-box.exr (compare it with: build/bin/aliquot compare A.exr B.exr)"
