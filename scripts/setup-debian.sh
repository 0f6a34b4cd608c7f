#!/usr/bin/env bash
# Installs the system dependencies of the workspace on Debian 12. Idempotent; every step
# checks first and installs only what is missing. Set ARPA_NO_APT=1 to never call apt-get.
# `--with-peers` also installs the Mitsuba 3 peers of `arpa bench` (scripts/install-peers.sh).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

# Embree 4 (arpa-cpu), with libclang for embree4-sys's bindgen.
bash scripts/install-embree4.sh
# Lavapipe with ray queries (Mesa >= 25 from bookworm-backports) and the Vulkan loader (arpa-wgpu).
bash scripts/install-lavapipe.sh
# The Khronos validation layer (arpa-vk's tests), glslc and the SPIR-V tools (arpa-vk).
bash scripts/install-vulkan-tools.sh
# Python 3 with venv, for the Python package (python/) and its tests.
bash scripts/install-python.sh
# The equal-time peers of `arpa bench`, on request.
for arg in "$@"; do
    case "$arg" in
        --with-peers) bash scripts/install-peers.sh ;;
        *) echo "setup-debian.sh: unknown option '$arg' (known: --with-peers)" >&2; exit 2 ;;
    esac
done
