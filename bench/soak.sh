#!/usr/bin/env bash
# Soak: replays box_small looped to FRAMES frames (default 20000) through the
# pipeline, as replay and the daemon run it, and judges the run: resident
# memory after warm-up flat within 10 %, p95 frame time of the last 1000
# frames within 10 % of the first 1000 after warm-up (docs/reliability.md).
#   bash bench/soak.sh [FRAMES] [WARMUP]
# Writes build/soak/soak.json (memory curve, per-1000-frame latency) and
# prints the two figures; exits 1 when one is out of bounds.
set -euo pipefail
cd "$(dirname "$0")/.."
frames="${1:-20000}"
warmup="${2:-2000}"
bash scripts/setup.sh > /dev/null
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > build.configure.log 2>&1 || { cat build.configure.log; exit 1; }
cmake --build build -j"$(nproc)" --target soak_bench > /dev/null
mkdir -p build/soak
status=0
build/bench/soak_bench --source recordings/box_small --work build/soak --frames "$frames" --warmup "$warmup" \
  --check 0.10 0.10 > build/soak/soak.json || status=$?
python3 - build/soak/soak.json <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print("soak: %d frames, RSS %.1f MB after warm-up (%d frames) -> %.1f MB at the end (x%.3f)" %
      (r["frames"], r["rss_after_warmup_mb"], r["warmup_frames"], r["rss_end_mb"], r["memory_growth"]))
print("soak: p95 frame time %.2f ms (first 1000 after warm-up) -> %.2f ms (last 1000), x%.3f" %
      (r["p95_first_ms"], r["p95_last_ms"], r["p95_ratio"]))
for b in r["latency_blocks"]:
    rss = [m["rss_mb"] for m in r["memory"] if b["first_frame"] < m["frame"] <= b["first_frame"] + 1000]
    print("  frames %6d-%6d  p50 %6.2f ms  p95 %6.2f ms  RSS %7.1f MB" %
          (b["first_frame"], b["first_frame"] + 999, b["p50_ms"], b["p95_ms"], rss[-1] if rss else 0))
PY
exit $status
