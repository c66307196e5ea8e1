# SPDX-License-Identifier: MIT
"""Paths and subprocess helpers for the Blender tests (no bpy here).

Locations (environment overrides):
  ATLAS_BUILD_DIR      the CMake build folder (default: <repo>/build)
  ATLAS_ADDON_PARENT   folder holding the atlas_defrag package (default: <build>/addon)
  ATLAS_MODELS_DIR     the shared test models (default: <repo>/../shared/models)
  BLENDER              Blender 3.x executable (default: blender)
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build")).resolve()
ADDON_PARENT = Path(os.path.abspath(os.environ.get("ATLAS_ADDON_PARENT", BUILD / "addon")))
ADDON_ZIP = BUILD / "atlas_defrag-0.1.0.zip"
BLENDER = os.environ.get("BLENDER", "blender")


def native_path():
    d = ADDON_PARENT / "atlas_defrag"
    hits = sorted(d.glob("_native*.so")) + sorted(d.glob("_native*.pyd"))
    return hits[0] if hits else None


def require_native():
    if native_path() is None:
        pytest.fail(f"the native module is missing from {ADDON_PARENT / 'atlas_defrag'}: "
                    "build it first (cmake --build build)")


def require_blender():
    if shutil.which(BLENDER) is None:
        pytest.fail(f"Blender 3.x executable '{BLENDER}' not found (set BLENDER)")


def run_blender(args, timeout=900, env=None):
    """blender --background --factory-startup ... ; returns CompletedProcess."""
    require_blender()
    cmd = [BLENDER, "--background", "--factory-startup", "--python-exit-code", "1"] + list(args)
    e = dict(os.environ)
    e.update(env or {})
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          timeout=timeout, env=e)
