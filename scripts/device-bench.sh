#!/usr/bin/env bash
# Table 2 on the GPU backends with the device's time per stage (issue 35): builds the
# release binary if needed (offline: no network is needed once the workspace has built
# here), runs bench/table2-gpu.toml on whatever adapter is present (a GPU, else lavapipe)
# and prints Table 2, the host's stage split and the device's time per stage.
#   bash scripts/device-bench.sh [OUT_DIR]      (default out/table2-gpu)
# The sweep is bounded by construction: it refuses a config whose runs × seconds exceed
# 300 s and stops the bench after 450 s (scene loading, pipeline compilation and the
# checkpoints' metrics add a few seconds per run), so the whole command stays under 8
# minutes once built. SECONDS_PER_RUN overrides the config's 10 s.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
# shellcheck disable=SC1091
[ -f .deps/embree4/env.sh ] && source .deps/embree4/env.sh
config=bench/table2-gpu.toml
out="${1:-out/table2-gpu}"
seconds="${SECONDS_PER_RUN:-$(python3 -c 'import sys, tomllib; print(tomllib.load(open(sys.argv[1], "rb"))["seconds"])' "$config")}"
runs=$(python3 -c '
import sys, tomllib
c = tomllib.load(open(sys.argv[1], "rb"))
print(len(c["scene"]) * len(c["backends"]) * len(c["methods"]) * len(c["photons"]))' "$config")
budget=$(python3 -c 'import sys; print(int(float(sys.argv[1]) * int(sys.argv[2])))' "$seconds" "$runs")
if [ "$budget" -gt 300 ]; then
  echo "device-bench: $runs runs × $seconds s = $budget s of rendering is over the 300 s this script allows" >&2
  exit 2
fi
echo "device-bench: $runs runs × $seconds s = $budget s of rendering (bench stopped after 450 s)" >&2

start=$(date +%s)
cargo build --release --offline --bin arpa
echo "device-bench: build $(( $(date +%s) - start )) s" >&2
rm -rf "$out"
start=$(date +%s)
timeout 450 "${CARGO_TARGET_DIR:-target}/release/arpa" bench "$config" --out "$out" --seconds "$seconds"
echo "device-bench: bench $(( $(date +%s) - start )) s" >&2

# The devices, Table 2 per backend, the host's stage split and the device's time per stage.
grep -E '^- (devices|commit|machine):' "$out/table.md"
awk '/^## /{ show = ($0 ~ /^## (Table 2|ATI by stage|Device time by stage)/) } show' "$out/table.md"
