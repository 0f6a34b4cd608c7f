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
# arpa-core in each of its feature sets (none, alloc, std): clippy and its docs without a
# warning (the std set is covered by the workspace runs below).
for features in "--no-default-features" "--no-default-features --features alloc"; do
  # shellcheck disable=SC2086
  cargo clippy -p arpa-core $features -- -D warnings
  # shellcheck disable=SC2086
  RUSTDOCFLAGS="-D warnings" cargo doc -p arpa-core --no-deps $features
done
# A crate outside the workspace uses arpa-core by path without std or alloc: a #![no_std]
# binary with its own panic handler and C main, linked against libc. Both profiles build
# without a warning and reproduce the point-light-over-plane irradiance (exit status 1
# when they do not).
RUSTFLAGS="-D warnings" cargo run --manifest-path arpa-core/tests/no-std-link/Cargo.toml
RUSTFLAGS="-D warnings" cargo run --release --manifest-path arpa-core/tests/no-std-link/Cargo.toml
cargo clippy --manifest-path arpa-core/tests/no-std-link/Cargo.toml -- -D warnings
# Lints and docs of the whole workspace, warnings denied.
cargo clippy --workspace --all-targets -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps
# Unit, integration and benchmark targets (benchmarks run once each, as smoke tests).
cargo test --workspace --all-targets
cargo test --workspace --doc
# arpa-core's examples for renderer authors (built above, run here): each compares with an
# exact answer and exits non-zero on a mismatch. wgsl_twin needs a wgpu adapter (lavapipe);
# without one it skips, unless CI is set.
cargo run -p arpa-core --example renderer_author
cargo run -p arpa-core --example wgsl_twin
