#!/usr/bin/env bash
# Configures and builds build-asan/: the tree with clang under
# AddressSanitizer and UndefinedBehaviorSanitizer, with the libFuzzer targets
# of fuzz/ beside the tests, so both share one compile of the libraries
# (`scripts/test.sh --sanitize` runs the tests, `scripts/fuzz.sh` the fuzzers).
# Extra arguments are targets to build instead of everything.
# clang, not gcc: gcc's UBSan instrumentation doubles the optimiser's time on
# the Ceres and Eigen templates (bundle_adjuster.cpp: 77 s against 36 s), and
# the fuzzers need clang anyway.
set -euo pipefail
cd "$(dirname "$0")/.."
# -gline-tables-only: file:line is all a sanitizer's stack trace needs.
BUILD_DIR=build-asan BUILD_TYPE=RelWithDebInfo BUILD_TARGETS="$*" bash scripts/build.sh \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DTAGSFM_SANITIZE=ON -DTAGSFM_FUZZ=ON -DTAGSFM_BUILD_BENCH=OFF \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only -DNDEBUG"
