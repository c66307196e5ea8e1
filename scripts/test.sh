#!/usr/bin/env bash
# Builds everything and runs every test: GoogleTest through ctest, then pytest
# (the module on the real scans, and the add-on in Blender 3.4 and bpy 4.5),
# then the C++ tests and the module's suite again under ASan + UBSan. pytest
# runs on one worker per core, a test file per worker (the Blender suites
# share one Blender process per group of scenarios within a file).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
ctest --test-dir build --output-on-failure -j"$(nproc)"
.venv/bin/python -m pytest python_tests -q -n "$(nproc)" --dist loadfile
bash scripts/test_sanitized.sh
