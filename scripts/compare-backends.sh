#!/usr/bin/env bash
# Renders the default scene and every shared scene with two backends at the same settings
# and prints, per scene, the whole-image mean of the second over the first's and each one's
# relMSE against the scene's independent reference (equal iterations). The numbers issue 20
# asks of the vk backend ("mean within 2 % of cpu, relMSE within 1.5x of cpu's").
#
#   bash scripts/compare-backends.sh [BASE [TEST [ITERATIONS [PHOTONS]]]]
#     defaults: cpu vk 8 100000; images go to target/compare-backends/
#
# Needs the release binary and example (built here) and ../shared/scenes.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BASE="${1:-cpu}"; TEST="${2:-vk}"; IT="${3:-8}"; PH="${4:-100000}"
SCENES="${ARPA_SHARED_SCENES:-../shared/scenes}"
OUT=target/compare-backends
mkdir -p "$OUT"
[ -f .deps/embree4/env.sh ] && source .deps/embree4/env.sh
cargo build --release -q --bin arpa --example region_means
ARPA=target/release/arpa
MEANS=target/release/examples/region_means

# scene reference (the same references the conformance suite uses)
refs=(
  "cornell-caustic cornell-caustic_mitsuba-path_256x256_4096spp_143s.exr"
  "caustic-glass caustic-glass_luxcore-pathcpu-photongi1_320x180_333spp_368s.exr"
  "water-caustic water-caustic_luxcore-pathcpu-photongi1_256x256_294spp_902s.exr"
  "veach-bidir veach-bidir_mitsuba-path_256x256_8192spp_304s.exr"
  "sponza-standin sponza-standin_mitsuba-path_320x180_1024spp_81s.exr"
)

ratio() { "$MEANS" "$1" "$2" | awk '$1 == "whole" { print $NF }'; }
relmse() { "$MEANS" "$1" "$2" | awk '$1 == "relMSE" { print $2 }'; }

printf '%-16s %12s %14s %14s %10s\n' scene "mean $TEST/$BASE" "relMSE $BASE" "relMSE $TEST" "ratio"
render() { "$ARPA" render "$@" --photons "$PH" --iterations "$IT" --seed 1 > /dev/null 2>&1; }
for b in "$BASE" "$TEST"; do render --backend "$b" --resolution 128x128 --out "$OUT/default-$b.exr"; done
printf '%-16s %12s %14s %14s %10s\n' default "$(ratio "$OUT/default-$BASE.exr" "$OUT/default-$TEST.exr")" - - -
for entry in "${refs[@]}"; do
  read -r name ref <<<"$entry"
  reference="$SCENES/$name/reference/$ref"
  for b in "$BASE" "$TEST"; do render "$SCENES/$name/scene.xml" --backend "$b" --out "$OUT/$name-$b.exr"; done
  rb="$(relmse "$reference" "$OUT/$name-$BASE.exr")"; rt="$(relmse "$reference" "$OUT/$name-$TEST.exr")"
  printf '%-16s %12s %14s %14s %10s\n' "$name" "$(ratio "$OUT/$name-$BASE.exr" "$OUT/$name-$TEST.exr")" "$rb" "$rt" \
    "$(awk -v a="$rt" -v b="$rb" 'BEGIN { printf "%.3f", a / b }')"
done
