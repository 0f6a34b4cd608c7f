#!/usr/bin/env bash
# Renders the loader's feature scenes (bench/scenes/features) on each backend given and prints
# the region means of bench/scenes/features/README.md against each scene's Mitsuba reference,
# as the table of bench/results/features.md:
#   bash scripts/feature-regions.sh [SECONDS] [BACKEND...]     (default: 20 s, cpu wgpu vk)
# SCENES="envmap mask" picks scenes (default: all of them).
# Needs a release build (cargo build --release) and, for the GPU backends, a Vulkan device
# (lavapipe is enough). Images go to ${OUT:-target/feature-regions}.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-20}
shift || true
backends=("$@")
[ ${#backends[@]} -gt 0 ] || backends=(cpu wgpu vk)
out=${OUT:-target/feature-regions}
mkdir -p "$out"
features=bench/scenes/features
arpa=target/release/arpa
means=target/release/examples/region_means
[ -x "$means" ] || cargo build -q --release --example region_means

# The regions: the README's table rows "| scene | `r0-r1,c0-c1` | what |".
regions() {
    grep -E '^\| [a-z]+ \| `[0-9]' "$features/README.md" | awk -F'|' -v s="$1" '{gsub(/ /,"",$2); if ($2 == s) {r=$3; gsub(/[ `]/,"",r); w=$4; gsub(/^ +| +$/,"",w); print r "|" w}}'
}

echo "| scene | backend | region | what | Mitsuba Y | arpa Y | ratio Y (R, G, B) |"
echo "|---|---|---|---|---|---|---|"
for scene in ${SCENES:-checkerboard bitmap mask serialized spectrum shapes thindielectric envmap}; do
    ref=$(ls "$features/$scene"/reference/*.exr)
    for backend in "${backends[@]}"; do
        img="$out/$scene-$backend"
        "$arpa" render "$features/$scene/scene.xml" --backend "$backend" --time "$seconds" --seed 1 --photons 250000 --out "$img" >"$img.log" 2>&1 \
            || { echo "| $scene | $backend | render failed: see $img.log | | | | |"; continue; }
        args=()
        whats=()
        while IFS='|' read -r region what; do
            args+=("r${#args[@]}:$region")
            whats+=("$region|$what")
        done < <(regions "$scene")
        i=0
        "$means" "$ref" "$img.exr" "${args[@]}" | awk '$1 ~ /^r[0-9]+$/' | while read -r _ r0 g0 b0 r1 g1 b1 rr rg rb _; do
            IFS='|' read -r region what <<<"${whats[$i]}"
            awk -v s="$scene" -v be="$backend" -v reg="$region" -v w="$what" -v r0="$r0" -v g0="$g0" -v b0="$b0" -v r1="$r1" -v g1="$g1" -v b1="$b1" -v rr="$rr" -v rg="$rg" -v rb="$rb" 'BEGIN {
                y0 = 0.212671*r0 + 0.715160*g0 + 0.072169*b0; y1 = 0.212671*r1 + 0.715160*g1 + 0.072169*b1;
                printf "| %s | %s | `%s` | %s | %.4f | %.4f | %.3f (%.3f, %.3f, %.3f) |\n", s, be, reg, w, y0, y1, y1 / y0, rr, rg, rb }'
            i=$((i + 1))
        done
    done
done
