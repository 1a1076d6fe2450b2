#!/usr/bin/env bash
# Set up, build, and run every test.
#   bash scripts/test.sh               Release build in build/, all tests
#   bash scripts/test.sh --sanitize    ASan+UBSan build in build-asan/, all but *Slow suites
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [ "${1:-}" = "--sanitize" ]; then
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  BUILD_DIR=build-asan BUILD_TYPE=RelWithDebInfo bash scripts/build.sh -DTAGSFM_SANITIZE=ON -DTAGSFM_BUILD_BENCH=OFF
  ctest --test-dir build-asan --output-on-failure -j"$(nproc)" -E 'Slow\.'
else
  bash scripts/build.sh
  ctest --test-dir build --output-on-failure -j"$(nproc)"
fi
