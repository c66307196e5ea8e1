#!/usr/bin/env bash
# Installs what Atlas Defrag needs on Debian 12 (run as root), creates .venv
# with the pinned PyPI packages (bpy 4.5) and .venv-bpy5 beside it (bpy 5.0, for
# python_tests/blender/test_bl_bpy50.py), and builds the native module, the
# tests and the add-on zip into build/. Safe to run again: it only does what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

missing=()
for pkg in blender python3-numpy libeigen3-dev libdeflate-dev googletest libgtest-dev cmake g++ make python3-venv \
           assimp-testmodels xvfb xauth parallel; do
  dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
fi

[ -x .venv/bin/python ] || python3 -m venv .venv
.venv/bin/python -m pip install -q --disable-pip-version-check -r requirements.txt
[ -x .venv-bpy5/bin/python ] || python3 -m venv .venv-bpy5
.venv-bpy5/bin/python -m pip install -q --disable-pip-version-check -r requirements-bpy5.txt

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE="$PWD/.venv/bin/python" >/dev/null
cmake --build build -j"$(nproc)"
