# SPDX-License-Identifier: MIT
"""Blender tests: Blender 3.4 (Debian, subprocesses) and bpy 4.5 (in process).
Paths and environment overrides: see blenv.py."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from blenv import ADDON_PARENT, require_native  # noqa: E402

if str(ADDON_PARENT) not in sys.path:
    sys.path.insert(0, str(ADDON_PARENT))


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
