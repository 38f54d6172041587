#!/usr/bin/env bash
# CI-sized validation of Aliquot's built-in scenes against Mitsuba 3.
#
#   tests/validation/run.sh [ALIQUOT_BINARY]     (default: build/bin/aliquot)
#   tests/validation/run.sh --self-test          (Mitsuba against itself: checks this harness)
#
# For each scene of VALIDATION_SCENES (cornell-box, then cornell-caustics):
# 1. Makes sure .venv (repo root) exists and has mitsuba and numpy (pip-installs them).
# 2. Mitsuba reference at the scene's reference spp (cached under build/validation/,
#    keyed by scene, Mitsuba version, variant, resolution, spp and seed, so reruns skip it).
# 3. An independent Mitsuba render at VALIDATION_SPP spp (the "noise at that spp").
# 4. Aliquot at VALIDATION_SPP spp: aliquot render --scene SCENE ...
# 5. compare_to_mitsuba.py: (a) mean|ours-ref| <= tolerance * mean|mitsuba-ref|,
#    (b) image means within the mean tolerance. Exit status is non-zero on any failure.
#
# Environment overrides (defaults in brackets): VALIDATION_SCENES [cornell-box
# cornell-caustics], VALIDATION_RESOLUTION [128x128], VALIDATION_SPP [256],
# VALIDATION_REF_SPP [4096 box, 2048 caustics], VALIDATION_TOLERANCE [1.1 box, 1.15
# caustics], MITSUBA_VARIANT [scalar_rgb], VALIDATION_THREADS [all cores].
#
# Why 128x128 at 256 spp rather than 64x64 at 1024 (the same 4.2 M samples, the same
# cost): at 64x64 the error metric is dominated by the ~30 pixels on the light's edge
# (partial coverage of a radiance-18 emitter), so mean|image - ref| of a correct
# render varies by 5.3 % (relative std) from seed to seed and 11 % of pairs of correct
# Mitsuba renders differ by more than the 1.1 tolerance; at 128x128 it varies by
# 2.1 % and no pair of 22 seeds exceeded 1.095 (docs/VALIDATION.md).
# Caustics: fireflies make both the error (2.8 % relative std) and the image mean
# (0.23-0.30 % per image) noisier, hence its wider tolerances, and its reference has
# 2048 spp so that it costs what the box's does (Mitsuba's scalar_rgb traces caustics
# paths at about half the box's rate); docs/VALIDATION.md has the numbers.
# Cost with the defaults on 2 idle cores: about 1 minute a scene (the references, 67 M
# and 34 M samples, most of it; nothing on a rerun, as they are cached), plus the
# Aliquot renders.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
HERE="$ROOT/tests/validation"

SELF_TEST=0
ALIQUOT="${1:-build/bin/aliquot}"
if [[ "$ALIQUOT" == "--self-test" ]]; then
    SELF_TEST=1
elif [[ "$ALIQUOT" != /* && ! -e "$ALIQUOT" && -e "$ROOT/$ALIQUOT" ]]; then
    ALIQUOT="$ROOT/$ALIQUOT"
fi

SCENES="${VALIDATION_SCENES:-cornell-box cornell-caustics}"
RES="${VALIDATION_RESOLUTION:-128x128}"
SPP="${VALIDATION_SPP:-256}"
VARIANT="${MITSUBA_VARIANT:-scalar_rgb}"
THREADS="${VALIDATION_THREADS:-$(nproc 2>/dev/null || echo 2)}"
# Seeds: the reference uses REF_SEED.. (one per pass), the same-spp Mitsuba render
# MIT_SEED; the ranges never overlap, so the images are independent.
REF_SEED=1000
MIT_SEED=2
OURS_SEED=1
SELF_SEED=3      # --self-test: the Mitsuba image standing in for ours

if [[ $SELF_TEST == 0 && ! -x "$ALIQUOT" ]]; then
    echo "validation: aliquot binary not found or not executable: $ALIQUOT" >&2
    echo "validation: build it first, or run '$0 --self-test' to check the harness alone" >&2
    exit 2
fi

VENV="$ROOT/.venv"
PY="$VENV/bin/python"
if [[ ! -x "$PY" ]]; then
    echo "validation: creating $VENV" >&2
    python3 -m venv "$VENV"
fi
if ! "$PY" -c "import mitsuba, numpy" >/dev/null 2>&1; then
    echo "validation: installing mitsuba and numpy into .venv" >&2
    "$PY" -m pip install --quiet --disable-pip-version-check "mitsuba==3.9.1" "numpy>=1.24"
fi
MI_VERSION="$("$PY" -c 'import mitsuba; print(mitsuba.__version__)')"

OUT="$ROOT/build/validation"
mkdir -p "$OUT"

render_mitsuba() {  # scene spp seed out
    nice -n 10 "$PY" "$HERE/mitsuba_cornell.py" --scene "$1" --variant "$VARIANT" \
        --threads "$THREADS" --resolution "$RES" --spp "$2" --seed "$3" --out "$4"
}

validate_scene() {  # scene ref_spp tolerance mean_tolerance
    local scene=$1 ref_spp=$2 tolerance=$3 mean_tolerance=$4
    local ref="$OUT/mitsuba-${scene}-${RES}-${VARIANT}-${ref_spp}spp-seed${REF_SEED}"
    ref="$ref-v${MI_VERSION}.exr"
    local mit="$OUT/mitsuba-${scene}-${RES}-${SPP}spp-seed${MIT_SEED}.exr"
    local ours="$OUT/ours-${scene}-${RES}-${SPP}spp-seed${OURS_SEED}.exr"
    if [[ -s "$ref" ]]; then
        echo "validation: $scene: reusing reference $ref" >&2
    else
        echo "validation: $scene: Mitsuba $MI_VERSION $VARIANT reference, $RES at $ref_spp spp" >&2
        render_mitsuba "$scene" "$ref_spp" "$REF_SEED" "$ref.tmp.exr" || return 1
        mv "$ref.tmp.exr" "$ref" || return 1
    fi
    echo "validation: $scene: Mitsuba $RES at $SPP spp (seed $MIT_SEED)" >&2
    render_mitsuba "$scene" "$SPP" "$MIT_SEED" "$mit" || return 1

    if [[ $SELF_TEST == 1 ]]; then
        ours="$OUT/self-test-mitsuba-${scene}-${RES}-${SPP}spp-seed${SELF_SEED}.exr"
        echo "validation: $scene: self-test: a second Mitsuba render stands in for Aliquot" >&2
        render_mitsuba "$scene" "$SPP" "$SELF_SEED" "$ours" || return 1
    else
        echo "validation: $scene: Aliquot $RES at $SPP spp (seed $OURS_SEED)" >&2
        rm -f "$ours"
        "$ALIQUOT" render --scene "$scene" --resolution "$RES" --spp "$SPP" \
            --seed "$OURS_SEED" --out "$ours" || return 1
        if [[ ! -s "$ours" ]]; then
            echo "validation: $scene: aliquot wrote no image to $ours" >&2
            return 1
        fi
    fi
    echo "validation: $scene:" >&2
    "$PY" "$HERE/compare_to_mitsuba.py" --ours "$ours" --reference "$ref" --mitsuba "$mit" \
        --tolerance "$tolerance" --mean-tolerance "$mean_tolerance"
}

status=0
start=$SECONDS
for scene in $SCENES; do
    case $scene in
        # Tolerances: the error ratio's and the image mean's seed-to-seed spread at
        # 128x128 and 256 spp, about 3 sigma (compare_to_mitsuba.py, docs/VALIDATION.md).
        cornell-box) validate_scene "$scene" "${VALIDATION_REF_SPP:-4096}" \
            "${VALIDATION_TOLERANCE:-1.1}" 0.005 || status=1 ;;
        cornell-caustics) validate_scene "$scene" "${VALIDATION_REF_SPP:-2048}" \
            "${VALIDATION_TOLERANCE:-1.15}" 0.01 || status=1 ;;
        *) echo "validation: no Mitsuba version of scene $scene" >&2; status=2 ;;
    esac
done
echo "validation: $((SECONDS - start)) s" >&2
exit $status
