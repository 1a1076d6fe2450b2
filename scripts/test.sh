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
  ctest --test-dir build-asan --output-on-failure -j"$(nproc)" -E 'Slow\.'
elif [ "${1:-}" = "--tsan" ]; then
  # A race reported anywhere (the tests, or the tagsfm they start) fails the run.
  export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/scripts/tsan.supp"
  launcher=()
  command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  # -g1 as for ASan: full debug info of the Eigen and Ceres templates made
  # this build take over 30 min on two cores.
  cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTAGSFM_BUILD_BENCH=OFF -DTAGSFM_THREAD_TESTS_ONLY=ON "${launcher[@]}" \
    -DCMAKE_CXX_FLAGS="-fsanitize=thread" -DCMAKE_C_FLAGS="-fsanitize=thread" \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" > build-tsan.configure.log 2>&1 \
    || { cat build-tsan.configure.log; exit 1; }
  cmake --build build-tsan -j"$(nproc)" --target tagsfm tagsfm_thread_tests
  ctest --test-dir build-tsan --output-on-failure -j"$(nproc)" \
    -R '^(RunDaemon|ReplayRealtime|FrameQueue|DashboardServer|AprilTagWorkerPool)\.'
else
  bash scripts/build.sh
  ctest --test-dir build --output-on-failure -j"$(nproc)"
fi
