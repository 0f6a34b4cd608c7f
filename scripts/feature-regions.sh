#!/usr/bin/env bash
# Renders the loader's feature scenes (bench/scenes/features) on each backend given and prints
# the region means of bench/scenes/features/README.md against each scene's Mitsuba reference,
# as the table of bench/results/features.md:
#   bash scripts/feature-regions.sh [SECONDS] [BACKEND...]     (default: 20 s, cpu wgpu vk)
# SCENES="envmap mask" picks scenes (default: all of them). FEATURES=bench/scenes/gltf with
# SCENES from its README measures the glTF test set (each scene.gltf, at 128x128, against
# the Mitsuba reference of its XML twin).
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
features=${FEATURES:-bench/scenes/features}
arpa=target/release/arpa
means=target/release/examples/region_means
[ -x "$means" ] || cargo build -q --release --example region_means

# The regions: the README's table rows "| scene | `r0-r1,c0-c1` | what |", with an optional
# fourth column naming the reference's integrator (e.g. `ptracer`) where a scene has several
# references (default: the scene's only, or first, reference).
regions() {
    grep -E '^\| [a-z-]+ \| `[0-9]' "$features/README.md" | awk -F'|' -v s="$1" '{gsub(/ /,"",$2); if ($2 == s) {r=$3; gsub(/[ `]/,"",r); w=$4; gsub(/^ +| +$/,"",w); i=$5; gsub(/[ `]/,"",i); print r "|" w "|" i}}'
}

echo "| scene | backend | region | what | Mitsuba Y | arpa Y | ratio Y (R, G, B) |"
echo "|---|---|---|---|---|---|---|"
for scene in ${SCENES:-checkerboard bitmap mask serialized spectrum shapes thindielectric envmap normalmap null blendbsdf materials}; do
    for backend in "${backends[@]}"; do
        img="$out/$scene-$backend"
        file="$features/$scene/scene.xml"
        extra=()
        if [ -f "$features/$scene/scene.gltf" ]; then
            file="$features/$scene/scene.gltf"
            extra=(--resolution 128x128)
        fi
        "$arpa" render "$file" "${extra[@]}" --backend "$backend" --time "$seconds" --seed 1 --photons 250000 --out "$img" >"$img.log" 2>&1 \
            || { echo "| $scene | $backend | render failed: see $img.log | | | | |"; continue; }
        while IFS='|' read -r region what integrator; do
            if [ -n "$integrator" ]; then
                ref=$(ls "$features/$scene"/reference/*_mitsuba-"$integrator"_*.exr)
            else
                ref=$(ls "$features/$scene"/reference/*.exr | head -1)
            fi
            "$means" "$ref" "$img.exr" "r:$region" | awk '$1 == "r"' | while read -r _ r0 g0 b0 r1 g1 b1 rr rg rb _; do
                [ -n "$integrator" ] && what="$what (vs $integrator)"
                awk -v s="$scene" -v be="$backend" -v reg="$region" -v w="$what" -v r0="$r0" -v g0="$g0" -v b0="$b0" -v r1="$r1" -v g1="$g1" -v b1="$b1" -v rr="$rr" -v rg="$rg" -v rb="$rb" 'BEGIN {
                    y0 = 0.212671*r0 + 0.715160*g0 + 0.072169*b0; y1 = 0.212671*r1 + 0.715160*g1 + 0.072169*b1;
                    printf "| %s | %s | `%s` | %s | %.4f | %.4f | %.3f (%.3f, %.3f, %.3f) |\n", s, be, reg, w, y0, y1, y1 / y0, rr, rg, rb }'
            done
        done < <(regions "$scene")
    done
done
