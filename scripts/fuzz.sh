#!/usr/bin/env bash
# Fuzzes the scene-file loaders with cargo-fuzz (libFuzzer): targets scene_xml (Mitsuba
# XML), ply (ASCII and binary), obj, serialized (Mitsuba's compressed meshes) and texture
# (the image files of bitmap textures) and gltf (glTF JSON and GLB) in fuzz/,
# each for EXECUTIONS runs (default 10^6).
#
#   scripts/fuzz.sh [EXECUTIONS] [TARGET...]
#
# Needs a nightly toolchain (`cargo +nightly`); without one it says so loudly and exits 0
# (the stable regression tests, tests/fuzz_regressions.rs, still replay every kept input).
# Installs cargo-fuzz when missing. Seeds each corpus with the kept minimal corpus
# (fuzz/corpus/<target>/, in the repository) plus the shared scenes' files: scene.xml,
# and the first bytes of each PLY and OBJ mesh (ARPA_SHARED_SCENES, default
# ../shared/scenes). The working corpus grows under $ARPA_FUZZ_WORK (default
# target/fuzz-work, not in the repository). Crashes, hangs (timeouts) and out-of-memory
# inputs are written to fuzz/artifacts/<target>/ and fail the script; copy each into
# fuzz/regressions/<target>/ once fixed, so that `cargo test` replays it on stable.
#
# Environment: ARPA_FUZZ_SANITIZER (default none: the loaders are safe Rust; "address"
# works too, slower), ARPA_FUZZ_TARGET_DIR (cargo target dir of the fuzz build, default
# target/fuzz), ARPA_FUZZ_TIMEOUT (libFuzzer -timeout per input, seconds, default 10),
# ARPA_FUZZ_RSS_MB (libFuzzer -rss_limit_mb, default 2048).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
root=$PWD

runs=${1:-1000000}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene_xml ply obj serialized texture gltf)
case $runs in '' | *[!0-9]*) echo "fuzz.sh: EXECUTIONS must be a number, got '$runs'" >&2; exit 2 ;; esac

if ! cargo +nightly --version >/dev/null 2>&1; then
  echo "################################################################################"
  echo "## fuzz.sh: SKIPPED: no nightly toolchain ('cargo +nightly' fails)."
  echo "## Install one with 'rustup toolchain install nightly' to fuzz the loaders."
  echo "## The stable regression tests (tests/fuzz_regressions.rs) still run."
  echo "################################################################################"
  exit 0
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  echo "fuzz.sh: installing cargo-fuzz"
  cargo +nightly install cargo-fuzz --locked
fi

shared=${ARPA_SHARED_SCENES:-$root/../shared/scenes}
work=${ARPA_FUZZ_WORK:-$root/target/fuzz-work}
target_dir=${ARPA_FUZZ_TARGET_DIR:-$root/target/fuzz}
sanitizer=${ARPA_FUZZ_SANITIZER:-none}
timeout=${ARPA_FUZZ_TIMEOUT:-10}
rss=${ARPA_FUZZ_RSS_MB:-2048}
# Seeds are cut to the inputs libFuzzer generates (-max_len), so that the fuzzer mutates
# headers and first records of real meshes rather than megabytes of vertices.
max_len=${ARPA_FUZZ_MAX_LEN:-8192}

# Seed corpus: the kept minimal corpus, then the shared scenes' files.
seed() {
  local t=$1 dir=$work/corpus/$t
  mkdir -p "$dir"
  if [ -d "fuzz/corpus/$t" ]; then cp -n fuzz/corpus/"$t"/* "$dir"/ 2>/dev/null || true; fi
  if [ ! -d "$shared" ]; then
    echo "fuzz.sh: no shared scenes at $shared (set ARPA_SHARED_SCENES); seeding $t with fuzz/corpus only"
    return
  fi
  local pattern
  case $t in
    scene_xml) pattern='*.xml' ;;
    ply) pattern='*.ply' ;;
    obj) pattern='*.obj' ;;
    serialized) pattern='*.serialized' ;;
    texture) pattern='*.png' ;;
    gltf) pattern='*.gltf' ;;
  esac
  local n=0 f name
  while IFS= read -r -d '' f; do
    name=shared-$(basename "$(dirname "$(dirname "$f")")")-$(basename "$f")
    [ "$t" = scene_xml ] && name=shared-$(basename "$(dirname "$f")")-$(basename "$f")
    dd if="$f" of="$dir/$name" bs="$max_len" count=1 status=none
    n=$((n + 1))
  done < <(find "$shared" -name "$pattern" -type f -print0)
  echo "fuzz.sh: $t: $n seed(s) from $shared"
}

status=0
for t in "${targets[@]}"; do
  seed "$t"
  mkdir -p "fuzz/artifacts/$t"
  echo "fuzz.sh: $t: $runs executions (sanitizer $sanitizer)"
  start=$(date +%s)
  if ! cargo +nightly fuzz run --sanitizer "$sanitizer" --debug-assertions --target-dir "$target_dir" "$t" "$work/corpus/$t" -- \
    -runs="$runs" -max_len="$max_len" -timeout="$timeout" -rss_limit_mb="$rss" -malloc_limit_mb="$rss" \
    -artifact_prefix="$root/fuzz/artifacts/$t/" -print_final_stats=1; then
    echo "fuzz.sh: $t FAILED: reproducer in fuzz/artifacts/$t/" >&2
    status=1
  fi
  echo "fuzz.sh: $t: finished in $(( $(date +%s) - start )) s"
done
exit $status
