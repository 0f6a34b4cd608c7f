#!/usr/bin/env bash
# Installs the equal-time peers of `arpa bench` (scripts/peer_mitsuba.py): Mitsuba 3 and
# numpy from PyPI, and Debian's libllvm19 for Mitsuba's fast LLVM variant (without it the
# peers fall back to the much slower scalar variant). Idempotent; ARPA_NO_APT=1 forbids
# apt-get (then only the scalar variant runs unless libLLVM is already there).
set -euo pipefail
PY="${PYTHON:-python3}"
if "$PY" -c 'import mitsuba, drjit, numpy' 2>/dev/null; then
    echo "[install-peers] mitsuba present: $("$PY" -c 'import mitsuba; print(mitsuba.__version__)')"
else
    echo "[install-peers] pip install mitsuba==3.9.1 numpy"
    "$PY" -m pip install --quiet --disable-pip-version-check "mitsuba==3.9.1" numpy
fi
# Dr.Jit's LLVM backend needs libLLVM 19 here: with Debian 12's own libLLVM 14 or 15 its
# kernels fail to compile, so another version being present is not enough.
if ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1; then
    echo "[install-peers] libLLVM 19 present"
elif [ "${ARPA_NO_APT:-0}" = 1 ]; then
    echo "[install-peers] ARPA_NO_APT=1: not installing libllvm19 (Mitsuba runs scalar_rgb)"
else
    echo "[install-peers] apt-get install libllvm19"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19
fi
