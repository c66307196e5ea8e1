#!/usr/bin/env bash
# The C++ tests and the module's pytest suite again, built with AddressSanitizer
# and UndefinedBehaviorSanitizer (build-asan/, Eigen's assertions on). Any
# report fails the run. Called by scripts/test.sh after the Release suites.
set -euo pipefail
cd "$(dirname "$0")/.."
# -O1 -g without NDEBUG: RelWithDebInfo's own flags define NDEBUG, which turns
# Eigen's assertions off, and -O2 takes longer to build than the tests run.
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
      -DATLAS_SANITIZE=ON -DPython_EXECUTABLE="$PWD/.venv/bin/python" >/dev/null
cmake --build build-asan -j"$(nproc)"
# Python itself is not instrumented and frees little at exit: leaks are not checked.
export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# The 10,000-chart packing stress, in C++ and in Python, runs in the Release
# suites only: under the sanitizers each took most of its suite's time, and
# the packer's memory use is checked here by the other packing tests.
ctest --test-dir build-asan --output-on-failure -j"$(nproc)" -E TenThousandStacked
# Python is not linked against libstdc++: preloaded with ASan's runtime, its
# __cxa_throw is there for ASan to intercept when the module throws.
LD_PRELOAD="$(g++ -print-file-name=libasan.so) $(g++ -print-file-name=libstdc++.so)" \
  ATLAS_BUILD_DIR="$PWD/build-asan" PYTHONPATH="$PWD/build-asan/addon" \
  .venv/bin/python -m pytest python_tests/test_native.py python_tests/test_options.py python_tests/test_degenerate_input.py -q -p no:cacheprovider \
  -n "$(nproc)" --dist load -k "not ten_thousand_stacked"
