#!/usr/bin/env bash
# Installs what the Python package (python/) needs to build and test on Debian 12: Python 3
# with its venv module (the test script makes a venv; pip then fetches maturin, numpy and
# pytest from PyPI) and python3-dev (libpython, which a plain `cargo test --workspace` links
# the extension crate's empty test harness against). Idempotent: checks first and changes
# nothing once everything is there.
#
# Environment:
#   ARPA_NO_APT=1         never call apt-get (fail instead if something is missing).
set -euo pipefail

log() { printf '[install-python] %s\n' "$*" >&2; }
die() { printf '[install-python] ERROR: %s\n' "$*" >&2; exit 1; }

venv_ok() {
    local probe
    probe="$(mktemp -d)"
    # ensurepip is what Debian splits into python3-venv: a venv without it has no pip.
    if python3 -m venv "$probe/v" >/dev/null 2>&1 && [[ -x "$probe/v/bin/pip" ]]; then rm -rf "$probe"; return 0; fi
    rm -rf "$probe"
    return 1
}

deb_installed() { [[ "$(dpkg-query -W -f='${Status}' "$1" 2>/dev/null)" == *"install ok installed"* ]]; }

if command -v python3 >/dev/null 2>&1 && venv_ok && deb_installed python3-dev; then
    log "python3 $(python3 -c 'import sys; print(sys.version.split()[0])') with venv, pip and python3-dev already installed"
    exit 0
fi
[[ "${ARPA_NO_APT:-0}" == 1 ]] && die "python3 with its venv module or python3-dev is missing; ARPA_NO_APT=1 forbids installing them"
command -v apt-get >/dev/null 2>&1 || die "apt-get not found; install python3 and python3-venv by hand"
as_root() {
    if [[ $(id -u) -eq 0 ]]; then "$@"
    elif command -v sudo >/dev/null 2>&1; then sudo "$@"
    else die "need root (or sudo) to run: $*"; fi
}
log "apt-get install python3 python3-venv python3-dev"
as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends python3 python3-venv python3-dev >/dev/null
venv_ok || die "python3 -m venv still fails after installing python3-venv"
log "installed python3 $(python3 -c 'import sys; print(sys.version.split()[0])') with venv"
