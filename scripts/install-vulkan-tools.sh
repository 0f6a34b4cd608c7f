#!/usr/bin/env bash
# Installs the Vulkan tools the `arpa-vk` crate needs on Debian 12 (bookworm): the Khronos
# validation layer its tests run under, and the shader compilers and SPIR-V tools for its
# GLSL stages. Idempotent: it checks first and changes nothing once everything is in place.
#
# Environment:
#   ARPA_NO_APT=1         never call apt-get (fail instead if something is missing).
#
# What it installs (all from bookworm's main archive)
#   vulkan-validationlayers  VK_LAYER_KHRONOS_validation
#                            (/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json)
#   glslc                    shaderc's GLSL -> SPIR-V compiler
#   spirv-tools              spirv-val, spirv-dis, spirv-opt
#   glslang-tools            glslangValidator
set -euo pipefail

PACKAGES=(vulkan-validationlayers glslc spirv-tools glslang-tools)

log() { printf '[install-vulkan-tools] %s\n' "$*" >&2; }
die() { printf '[install-vulkan-tools] ERROR: %s\n' "$*" >&2; exit 1; }

as_root() {
    if [[ $(id -u) -eq 0 ]]; then "$@"
    elif command -v sudo >/dev/null 2>&1; then sudo "$@"
    else die "need root (or sudo) to run: $*"; fi
}
deb_version() { dpkg-query -W -f='${Status} ${Version}' "$1" 2>/dev/null | sed -n 's/^install ok installed //p'; }
layer_ok() { compgen -G '/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json' >/dev/null; }
tools_ok() { command -v glslc >/dev/null && command -v spirv-val >/dev/null && command -v glslangValidator >/dev/null; }

missing=()
for p in "${PACKAGES[@]}"; do
    [[ -n "$(deb_version "$p")" ]] || missing+=("$p")
done

if [[ ${#missing[@]} -eq 0 ]] && layer_ok && tools_ok; then
    for p in "${PACKAGES[@]}"; do log "$p $(deb_version "$p") already installed"; done
    exit 0
fi
# Installed packages whose files are gone: reinstall them all.
[[ ${#missing[@]} -eq 0 ]] && missing=("${PACKAGES[@]}")

[[ "${ARPA_NO_APT:-0}" == 1 ]] && die "missing ${missing[*]}; ARPA_NO_APT=1 forbids installing them"
command -v apt-get >/dev/null 2>&1 || die "apt-get not found; install ${missing[*]} by hand"

codename="$(. /etc/os-release 2>/dev/null && echo "${VERSION_CODENAME:-}")"
[[ "$codename" == bookworm ]] || log "WARNING: this is '$codename', not Debian 12 (bookworm); installing from its own archive"

log "apt-get update"
as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
log "apt-get install ${missing[*]}"
as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null

for p in "${PACKAGES[@]}"; do
    [[ -n "$(deb_version "$p")" ]] || die "$p did not install"
done
layer_ok || die "vulkan-validationlayers installed but no VkLayer_khronos_validation.json in /usr/share/vulkan/explicit_layer.d"
tools_ok || die "glslc, spirv-val or glslangValidator missing from PATH after installing"
for p in "${PACKAGES[@]}"; do log "installed $p $(deb_version "$p")"; done
