#!/usr/bin/env bash
# The project's test command (README.md, "Test"). Installs what the workspace needs on a
# fresh Debian 12 machine (scripts/setup-debian.sh), then builds and tests everything.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash scripts/setup-debian.sh
# shellcheck disable=SC1091
[ -f .deps/embree4/env.sh ] && source .deps/embree4/env.sh

# arpa-vk's GLSL stages: recompile, compare with the checked-in SPIR-V, spirv-val.
bash scripts/build-vk-shaders.sh --check
# arpa-core must build without std and without alloc, without a warning.
RUSTFLAGS="-D warnings" cargo build -p arpa-core --no-default-features
RUSTFLAGS="-D warnings" cargo build -p arpa-core --no-default-features --features alloc
# Lints and docs of the whole workspace, warnings denied.
cargo clippy --workspace --all-targets -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps
# Unit, integration and benchmark targets (benchmarks run once each, as smoke tests).
cargo test --workspace --all-targets
cargo test --workspace --doc
