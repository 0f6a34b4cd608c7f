#!/usr/bin/env bash
# Installs lavapipe (Mesa's software Vulkan driver) with ray-query support, which the
# `arpa-wgpu` crate needs when no GPU is present, on Debian 12 (bookworm). Idempotent:
# it checks first and changes nothing once everything is in place.
#
# Environment:
#   ARPA_NO_APT=1         never call apt-get (fail instead if something is missing).
#
# Why bookworm-backports: bookworm's own Mesa 22.3 lavapipe has no VK_KHR_ray_query
# (and no acceleration structures); Mesa 25.0 from bookworm-backports has both, which is
# what wgpu's EXPERIMENTAL_RAY_QUERY feature asks the driver for.
#
# What it installs
#   mesa-vulkan-drivers (>= 25, from bookworm-backports): lavapipe's ICD
#                        (libvulkan_lvp.so and /usr/share/vulkan/icd.d/lvp_icd.json)
#   libvulkan1          the Vulkan loader (libvulkan.so.1) that wgpu opens at run time
set -euo pipefail

MESA_MIN_VERSION="25"

log() { printf '[install-lavapipe] %s\n' "$*" >&2; }
die() { printf '[install-lavapipe] ERROR: %s\n' "$*" >&2; exit 1; }

as_root() {
    if [[ $(id -u) -eq 0 ]]; then "$@"
    elif command -v sudo >/dev/null 2>&1; then sudo "$@"
    else die "need root (or sudo) to run: $*"; fi
}
deb_version() { dpkg-query -W -f='${Status} ${Version}' "$1" 2>/dev/null | sed -n 's/^install ok installed //p'; }
mesa_ok() {
    local v; v="$(deb_version mesa-vulkan-drivers)"
    [[ -n "$v" ]] && dpkg --compare-versions "$v" ge "$MESA_MIN_VERSION"
}
loader_ok() { [[ -n "$(deb_version libvulkan1)" ]]; }
icd_ok() { compgen -G '/usr/share/vulkan/icd.d/lvp_icd*.json' >/dev/null; }

if mesa_ok && loader_ok && icd_ok; then
    log "mesa-vulkan-drivers $(deb_version mesa-vulkan-drivers) and libvulkan1 $(deb_version libvulkan1) already installed"
    exit 0
fi

missing="mesa-vulkan-drivers>=$MESA_MIN_VERSION (have: $(deb_version mesa-vulkan-drivers || true)), libvulkan1 (have: $(deb_version libvulkan1 || true))"
[[ "${ARPA_NO_APT:-0}" == 1 ]] && die "missing $missing; ARPA_NO_APT=1 forbids installing them"
command -v apt-get >/dev/null 2>&1 || die "apt-get not found; install $missing by hand"

codename="$(. /etc/os-release 2>/dev/null && echo "${VERSION_CODENAME:-}")"
[[ "$codename" == bookworm ]] || log "WARNING: this is '$codename', not Debian 12 (bookworm); trying bookworm-backports anyway"

# The URI of the machine's own Debian source for bookworm (a one-line `deb URI bookworm ...`
# entry or a deb822 stanza with `Suites: bookworm`): backports come from the same mirror the
# machine already uses, whatever it is; no host name is written here.
debian_uri() {
    local f
    for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
        [[ -f "$f" ]] || continue
        awk '$1 == "deb" { i = 2; if ($2 ~ /^\[/) { while (i <= NF && $i !~ /\]$/) i++; i++ }
             if ($(i + 1) == "bookworm") { print $i; exit } }' "$f"
    done
    for f in /etc/apt/sources.list.d/*.sources; do
        [[ -f "$f" ]] || continue
        # deb822: stanzas separated by blank lines; the first URI of a stanza of type deb
        # whose suites include bookworm.
        awk 'BEGIN { RS = ""; FS = "\n" }
             { uri = ""; deb = 0; suite = 0
               for (k = 1; k <= NF; k++) {
                 if ($k ~ /^Types:/ && $k ~ /(^|[ \t])deb([ \t]|$)/) deb = 1
                 if ($k ~ /^URIs:/) { split($k, u, /[ \t]+/); uri = u[2] }
                 if ($k ~ /^Suites:/ && $k ~ /(^|[ \t])bookworm([ \t]|$)/) suite = 1
               }
               if (deb && suite && uri != "") { print uri; exit } }' "$f"
    done
}

# bookworm-backports in the apt sources (one-line or deb822 format), unless already there.
if grep -rqs 'bookworm-backports' /etc/apt/sources.list /etc/apt/sources.list.d/; then
    log "bookworm-backports already in the apt sources"
else
    uri="$(debian_uri | head -n 1)"
    [[ -n "$uri" ]] || die "no Debian source for bookworm in /etc/apt/sources.list or /etc/apt/sources.list.d/ to take the backports mirror from; add 'deb <your mirror> bookworm-backports main' by hand"
    line="deb $uri bookworm-backports main"
    log "adding '$line' (the URI of the configured bookworm source) to /etc/apt/sources.list.d/bookworm-backports.list"
    printf '%s\n' "$line" | as_root tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
fi

log "apt-get update"
as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
log "apt-get install -t bookworm-backports mesa-vulkan-drivers libvulkan1"
as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    -t bookworm-backports mesa-vulkan-drivers libvulkan1 >/dev/null

mesa_ok || die "mesa-vulkan-drivers is $(deb_version mesa-vulkan-drivers), need >= $MESA_MIN_VERSION (bookworm-backports)"
loader_ok || die "libvulkan1 did not install"
icd_ok || die "mesa-vulkan-drivers installed but no lavapipe ICD (/usr/share/vulkan/icd.d/lvp_icd*.json)"
log "installed mesa-vulkan-drivers $(deb_version mesa-vulkan-drivers), libvulkan1 $(deb_version libvulkan1)"
