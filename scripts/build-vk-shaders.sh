#!/usr/bin/env bash
# Compiles arpa-vk's GLSL ray-tracing stages (the ones naga 30 cannot express: the gather's
# intersection and ignoring any-hit, and the test's ray generation and miss) into the
# checked-in SPIR-V under arpa-vk/shaders/spv/, which arpa-vk embeds with include_bytes!,
# and validates each module with spirv-val.
#
#   bash scripts/build-vk-shaders.sh          rewrite arpa-vk/shaders/spv/*.spv
#   bash scripts/build-vk-shaders.sh --check  recompile into a temporary directory, validate,
#                                             and fail if any checked-in file differs (CI)
#
# The bytes depend on the compiler: the checked-in SPIR-V is made by Debian's glslc (shaderc
# 2023.2, glslang 11.13). --check with another glslc version fails and says so.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SRC="$ROOT/arpa-vk/shaders"
OUT_DIR="$SRC/spv"
# Every GLSL stage (the file's extension gives glslc the stage).
STAGES=(gather.rint gather.rahit gather_test.rgen gather_test.rmiss)
# Pinned flags: SPIR-V 1.5 for Vulkan 1.2 (ray-tracing pipelines need 1.4+), optimised,
# warnings are errors, no debug info (no -g: no file paths in the bytes), includes from the
# shader directory only.
GLSLC_FLAGS=(--target-env=vulkan1.2 -O -Werror -I "$SRC")
SPIRV_VAL_FLAGS=(--target-env vulkan1.2)
EXPECTED_GLSLC="shaderc 2023.2"

for tool in glslc spirv-val; do
    if ! command -v "$tool" >/dev/null; then
        echo "build-vk-shaders: $tool not found (Debian: apt-get install glslc spirv-tools)" >&2
        exit 2
    fi
done
# The first line of --version; no `| head`, whose early exit would SIGPIPE glslc under pipefail.
version="$(glslc --version)"
version="${version%%$'\n'*}"

check=0
case "${1:-}" in
    --check) check=1 ;;
    "") ;;
    *) echo "usage: $0 [--check]" >&2; exit 2 ;;
esac

if [[ $check == 1 ]]; then
    dest="$(mktemp -d)"
    trap 'rm -rf "$dest"' EXIT
else
    dest="$OUT_DIR"
    mkdir -p "$dest"
fi

for stage in "${STAGES[@]}"; do
    # Compiled from the shader directory with a relative name (no path of this machine).
    (cd "$SRC" && glslc "${GLSLC_FLAGS[@]}" -o "$dest/$stage.spv" "$stage")
    spirv-val "${SPIRV_VAL_FLAGS[@]}" "$dest/$stage.spv"
done

if [[ $check == 0 ]]; then
    echo "build-vk-shaders: wrote ${STAGES[*]/%/.spv} to arpa-vk/shaders/spv ($version)"
    exit 0
fi

status=0
for stage in "${STAGES[@]}"; do
    want="$OUT_DIR/$stage.spv"
    if [[ ! -f "$want" ]]; then
        echo "build-vk-shaders --check: arpa-vk/shaders/spv/$stage.spv is missing" >&2
        status=1
    elif ! cmp -s "$dest/$stage.spv" "$want"; then
        echo "build-vk-shaders --check: arpa-vk/shaders/spv/$stage.spv differs from $stage compiled now" \
             "($(cmp "$dest/$stage.spv" "$want" 2>&1 || true))" >&2
        status=1
    fi
done
# Checked-in modules no stage makes any more.
for f in "$OUT_DIR"/*.spv; do
    [[ -e "$f" ]] || continue
    name="$(basename "$f" .spv)"
    if [[ " ${STAGES[*]} " != *" $name "* ]]; then
        echo "build-vk-shaders --check: arpa-vk/shaders/spv/$name.spv has no source stage" >&2
        status=1
    fi
done
if [[ $status != 0 ]]; then
    if [[ "$version" != "$EXPECTED_GLSLC"* ]]; then
        echo "build-vk-shaders --check: this glslc is '$version'; the checked-in SPIR-V was made by $EXPECTED_GLSLC" >&2
    fi
    echo "build-vk-shaders --check: FAILED; run bash scripts/build-vk-shaders.sh and commit arpa-vk/shaders/spv" >&2
    exit 1
fi
echo "build-vk-shaders --check: ${#STAGES[@]} modules valid and identical to the checked-in SPIR-V ($version)"
