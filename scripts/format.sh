#!/usr/bin/env bash
# Applies .clang-format to every C++ file git tracks; with --check, changes nothing and
# fails on the first file that differs (scripts/test.sh runs that).
set -euo pipefail
cd "$(dirname "$0")/.."
mapfile -t files < <(git ls-files '*.cpp' '*.h')
if [[ ${1:-} == --check ]]; then
    clang-format --dry-run -Werror "${files[@]}"
else
    clang-format -i "${files[@]}"
fi
