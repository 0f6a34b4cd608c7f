#!/usr/bin/env python3
"""Alternates `cpu_backend` runs of several builds or settings and keeps each one's best.

Timings drift between runs minutes apart, so two variants are compared only in
alternating runs (A B A B ...), each run's `interleaved.threads_1` line (raw Embree
ns/ray, ARPA and RTPM pass ns/segment, themselves best of 8 alternating rounds), and
the ratios are read against the lowest raw time of the whole set (DEVELOPERS.md, "The
CPU photon pass").

Usage:
    scripts/bench_alternate.py ROUNDS SPEC [SPEC ...]

SPEC is `BINARY` or `BINARY:NAME=VALUE[,NAME=VALUE...]` (extra environment for that
variant). BINARY is a copy of `target/release/deps/cpu_backend-*` (copy it after each
`cargo bench -p arpa-cpu --bench cpu_backend --no-run`, since the next build overwrites
it). Every run is `ARPA_CPU_BENCH_ONLY=raw,pass taskset -c 1 BINARY --bench`, about 30 s.
"""

import os
import re
import subprocess
import sys

LINE = re.compile(
    r"interleaved\.threads_1: raw ([\d.]+) ns/ray, arpa ([\d.]+) ns/segment.*rtpm ([\d.]+) ns/segment"
)


def run(spec):
    binary, _, extra = spec.partition(":")
    env = dict(os.environ, ARPA_CPU_BENCH_ONLY="raw,pass")
    for pair in filter(None, extra.split(",")):
        name, _, value = pair.partition("=")
        env[name] = value
    out = subprocess.run(
        ["taskset", "-c", "1", binary, "--bench"], env=env, capture_output=True, text=True
    )
    found = LINE.search(out.stdout)
    if out.returncode != 0 or not found:
        sys.exit(f"{spec}: no interleaved.threads_1 line (exit {out.returncode}):\n{out.stderr[-2000:]}")
    return [float(x) for x in found.groups()]


def main():
    if len(sys.argv) < 3 or not sys.argv[1].isdigit():
        sys.exit(__doc__)
    rounds, specs = int(sys.argv[1]), sys.argv[2:]
    best = {s: [float("inf")] * 3 for s in specs}
    for r in range(rounds):
        for s in specs:
            got = run(s)
            best[s] = [min(a, b) for a, b in zip(best[s], got)]
            print(f"round {r}: {s}: raw {got[0]:.1f} ns/ray, arpa {got[1]:.1f}, rtpm {got[2]:.1f} ns/segment", flush=True)
    low = min(v[0] for v in best.values())
    print(f"best of {rounds}, ratios against the set's lowest raw time ({low:.1f} ns/ray):")
    for s, (raw, arpa, rtpm) in best.items():
        print(
            f"  {s}: raw {raw:.1f} ns/ray, arpa {arpa:.1f} ns/segment ({100 * low / arpa:.1f} %), "
            f"rtpm {rtpm:.1f} ns/segment ({100 * low / rtpm:.1f} %)"
        )


if __name__ == "__main__":
    main()
