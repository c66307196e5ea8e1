# SPDX-License-Identifier: MIT
"""Blender tests: Blender 3.4 (Debian, subprocesses) and bpy 4.5 (in process).

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
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build")).resolve()
ADDON_PARENT = Path(os.path.abspath(os.environ.get("ATLAS_ADDON_PARENT", BUILD / "addon")))
ADDON_ZIP = BUILD / "atlas_defrag-0.1.0.zip"
BLENDER = os.environ.get("BLENDER", "blender")

for p in (str(HERE), str(ADDON_PARENT)):
    if p not in sys.path:
        sys.path.insert(0, p)


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


@pytest.fixture(scope="session")
def pkg():
    """The add-on package, registered in the bpy 4.5 module."""
    import bpy  # noqa: F401

    import atlas_defrag
    if Path(os.path.abspath(atlas_defrag.__file__)).parent.parent != ADDON_PARENT:
        pytest.fail(f"atlas_defrag imported from {atlas_defrag.__file__}, not {ADDON_PARENT}")
    atlas_defrag.register()
    yield atlas_defrag
    atlas_defrag.unregister()


@pytest.fixture(scope="session")
def native(pkg):
    require_native()
    from atlas_defrag import _native
    return _native


def run_blender(args, timeout=900, env=None):
    """blender --background --factory-startup ... ; returns CompletedProcess."""
    require_blender()
    cmd = [BLENDER, "--background", "--factory-startup", "--python-exit-code", "1"] + list(args)
    e = dict(os.environ)
    e.update(env or {})
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          timeout=timeout, env=e)
