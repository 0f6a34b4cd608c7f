#!/usr/bin/env bash
# Renders the shared Crytek Sponza from both of its forms (gltf/Sponza.gltf and scene.xml)
# on each backend given and prints the region means against its Mitsuba volpath reference:
# the whole image and the regions behind alpha masks (README, "glTF scenes"):
#   thorn   rows 84-98,   columns 96-112: the pillar seen through the cut-outs of the thorn
#           plant hanging from the gallery;
#   plant   rows 124-138, columns 46-74:  the red curtain seen through the left potted plant.
# A control render of the glTF form with its three MASK materials made OPAQUE (a copy of the
# JSON in the output folder; buffers and images linked), on the first backend, shows what
# the same regions read without the cut-outs.
#   bash scripts/sponza-cutouts.sh [ITERATIONS] [BACKEND...]     (default: 384, cpu wgpu vk)
# Needs a release build (cargo build --release), python3, the shared scenes
# (ARPA_SHARED_SCENES, default ../shared/scenes) and, for the GPU backends, a Vulkan device
# (lavapipe is enough). Images go to ${OUT:-target/sponza-cutouts}; CONTROL=0 skips the
# control render.
set -euo pipefail
cd "$(dirname "$0")/.."
iterations=${1:-384}
shift || true
backends=("$@")
[ ${#backends[@]} -gt 0 ] || backends=(cpu wgpu vk)
scenes=${ARPA_SHARED_SCENES:-../shared/scenes}
dir="$scenes/crytek-sponza"
[ -d "$dir" ] || { echo "sponza-cutouts.sh: no $dir (set ARPA_SHARED_SCENES)" >&2; exit 2; }
ref=$(ls "$dir"/reference/*.exr | head -1)
out=${OUT:-target/sponza-cutouts}
mkdir -p "$out"
arpa=target/release/arpa
means=target/release/examples/region_means
[ -x "$means" ] || cargo build -q --release --example region_means
regions=(whole:0-180,0-320 thorn:84-98,96-112 plant:124-138,46-74)

# The control: every alphaMode MASK made OPAQUE, the rest of the folder linked.
control="$out/opaque"
if [ "${CONTROL:-1}" != 0 ]; then
    mkdir -p "$control"
    for f in "$dir"/gltf/*; do
        [ "$(basename "$f")" = Sponza.gltf ] || ln -sf "$(realpath "$f")" "$control/"
    done
    python3 - "$dir/gltf/Sponza.gltf" "$control/Sponza.gltf" <<'EOF'
import json, sys
g = json.load(open(sys.argv[1]))
for m in g["materials"]:
    if m.get("alphaMode") == "MASK":
        m["alphaMode"] = "OPAQUE"
json.dump(g, open(sys.argv[2], "w"))
EOF
fi

echo "| form | backend | iterations | region | Mitsuba Y | arpa Y | ratio Y (R, G, B) |"
echo "|---|---|---|---|---|---|---|"
for backend in "${backends[@]}"; do
    forms=(gltf xml)
    # The control once, on the first backend.
    [ "${CONTROL:-1}" != 0 ] && [ "$backend" = "${backends[0]}" ] && forms+=(opaque)
    for form in "${forms[@]}"; do
        case $form in
            gltf) file="$dir/gltf/Sponza.gltf" ;;
            xml) file="$dir/scene.xml" ;;
            opaque) file="$control/Sponza.gltf" ;;
        esac
        img="$out/$form-$backend-$iterations"
        "$arpa" render "$file" --resolution 320x180 --backend "$backend" --iterations "$iterations" --seed 1 --out "$img" >"$img.log" 2>&1 \
            || { echo "| $form | $backend | $iterations | render failed: see $img.log | | | |"; continue; }
        "$means" "$ref" "$img.exr" "${regions[@]}" | awk -v f="$form" -v be="$backend" -v it="$iterations" 'NR > 3 {
            y0 = 0.212671*$2 + 0.715160*$3 + 0.072169*$4; y1 = 0.212671*$5 + 0.715160*$6 + 0.072169*$7;
            printf "| %s | %s | %s | %s | %.5f | %.5f | %.3f (%.3f, %.3f, %.3f) |\n", f, be, it, $1, y0, y1, y1 / y0, $8, $9, $10 }'
    done
done
