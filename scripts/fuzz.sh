#!/usr/bin/env bash
# Runs each libFuzzer target (fuzz/) for SECONDS (default 25) from the seed
# corpus in fuzz/corpus/<target>/. The targets are built in build-asan/ by
# scripts/build_asan.sh, beside the sanitizer tests (after
# `scripts/test.sh --sanitize` there is nothing left to build).
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]     e.g. bash scripts/fuzz.sh 600 ply
# New inputs that add coverage go to build-asan/fuzz/corpus/<target>/ (not the
# repository); a crash is written to build-asan/fuzz/artifacts/<target>/ and
# makes the script fail. One line per target: executions, and the outcome.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-25}"
shift || true
bash scripts/setup.sh
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=($(ls fuzz/corpus))
fi
bash scripts/build_asan.sh "${targets[@]/%/_fuzz}"
build=build-asan/fuzz

failed=0
for t in "${targets[@]}"; do
  mkdir -p "$build/corpus/$t" "$build/artifacts/$t"
  log="$build/$t.log"
  # -rss_limit_mb: a parser that allocates what a header claims is a finding.
  if "$build/${t}_fuzz" -max_total_time="$seconds" -timeout=60 -rss_limit_mb=2048 -print_final_stats=1 \
       -artifact_prefix="$build/artifacts/$t/" "$build/corpus/$t" "fuzz/corpus/$t" > "$log" 2>&1; then
    outcome="no crash"
  else
    outcome="FAILED: see $log and $build/artifacts/$t/"
    failed=1
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  echo "fuzz: $t: $runs executions in ${seconds}s, $outcome"
done
exit $failed
