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
# arpa-python has no Rust tests (its tests are the pytest suite below); excluded, cargo does
# not link a test harness of the extension module against libpython.
cargo test --workspace --exclude arpa-python --all-targets
cargo test --workspace --exclude arpa-python --doc
# arpa-core's examples for renderer authors (built above, run here): each compares with an
# exact answer and exits non-zero on a mismatch. wgsl_twin needs a wgpu adapter (lavapipe);
# without one it skips, unless CI is set.
cargo run -p arpa-core --example renderer_author
cargo run -p arpa-core --example wgsl_twin
# The Python package (python/, README "Python"): a fresh venv under the target directory
# with pinned pip, maturin, numpy and pytest from PyPI; `pip install ./python` with the
# `python-ci` profile (`pip install ./python` alone builds `release`; the package's feature
# set differs from the workspace's, so its dependencies cannot reuse the builds above and
# a cheap profile keeps that second build short); then its pytest suite, which compares
# `arpa.render` with the CLI that `cargo test` built.
target_dir="${CARGO_TARGET_DIR:-target}"
venv="$target_dir/python-venv"
python3 -m venv --clear "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check pip==26.3
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check maturin==1.16.0 numpy==2.4.6 pytest==9.2.0
PATH="$(cd "$venv/bin" && pwd):$PATH" "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    --no-build-isolation ./python --config-settings=build-args="--profile python-ci"
# Without LD_LIBRARY_PATH (env.sh sets it): the module must find Embree through its rpath.
env -u LD_LIBRARY_PATH ARPA_CLI="$(cd "$target_dir" && pwd)/debug/arpa" "$venv/bin/python" -m pytest -q -rs python/tests
