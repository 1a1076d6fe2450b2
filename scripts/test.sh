#!/usr/bin/env bash
# Set up, build, and run every test.
#   bash scripts/test.sh               Release build in build/, all tests
#   bash scripts/test.sh --sanitize    ASan+UBSan clang build in build-asan/ (scripts/build_asan.sh),
#                                      all but *Slow suites
#   bash scripts/test.sh --tsan        ThreadSanitizer build in build-tsan/ of the tests whose
#                                      threads meet: the daemon (run), realtime replay, the
#                                      frame queue, the dashboard, libapriltag's worker pool
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [ "${1:-}" = "--sanitize" ]; then
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  bash scripts/build_asan.sh
  # The bundled recordings' replay/run comparisons on box_photos only: each
  # of the three drives the same code, at 80-300 s a test under ASan (the
  # Release run compares all three).
  ctest --test-dir build-asan --output-on-failure -j"$(nproc)" \
    -E 'Slow\.|^BundledRecordings/PipelinePaths\.[A-Za-z]+/(box_small|wall_small)'
elif [ "${1:-}" = "--tsan" ]; then
  # A race reported anywhere (the tests, or the tagsfm they start) fails the run.
  export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/scripts/tsan.supp"
  # -g1, line tables only as for ASan: full debug info of the Eigen and Ceres templates made
  # this build take over 30 min on two cores. Only tagsfm and the one binary
  # of the threaded tests are built (TAGSFM_THREAD_TESTS_ONLY).
  BUILD_DIR=build-tsan BUILD_TYPE=RelWithDebInfo BUILD_TARGETS="tagsfm tagsfm_thread_tests" bash scripts/build.sh \
    -DTAGSFM_BUILD_BENCH=OFF -DTAGSFM_THREAD_TESTS_ONLY=ON \
    -DCMAKE_CXX_FLAGS="-fsanitize=thread" -DCMAKE_C_FLAGS="-fsanitize=thread" \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread"
  ctest --test-dir build-tsan --output-on-failure -j"$(nproc)" \
    -R '^(RunDaemon|ReplayRealtime|FrameQueue|DashboardServer|AprilTagWorkerPool)\.'
else
  bash scripts/build.sh
  ctest --test-dir build --output-on-failure -j"$(nproc)"
fi
