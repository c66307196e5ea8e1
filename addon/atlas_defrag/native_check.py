# SPDX-License-Identifier: MIT
"""Whether the native module loads here, and if not, why in the user's terms:
the platform and Python it was built for against the ones running. No bpy."""

from __future__ import annotations

import importlib
import os
import platform
import re
import sys
from functools import lru_cache

# Blender's platform names (the manifest's `platforms`) by (system, machine).
_PLATFORMS = {("linux", "x86_64"): "linux-x64", ("linux", "aarch64"): "linux-arm64",
              ("windows", "amd64"): "windows-x64", ("windows", "arm64"): "windows-arm64",
              ("darwin", "arm64"): "macos-arm64", ("darwin", "x86_64"): "macos-x64"}

# cpython-311-x86_64-linux-gnu, cp311-win_amd64, cpython-310-darwin: Python and platform words.
_TAG = re.compile(r"_native\.(?:cpython-|cp)(\d)(\d+)[-_]?(.*)\.(so|pyd)$")


def running() -> str:
    """'linux-x64, Python 3.11' for this process."""
    key = (platform.system().lower(), platform.machine().lower())
    name = _PLATFORMS.get(key, f"{key[0]}-{key[1]}")
    return f"{name}, Python {sys.version_info[0]}.{sys.version_info[1]}"


def built_for(filename: str) -> str:
    """'linux-x64, Python 3.11' from a module file name, or the name itself."""
    m = _TAG.search(filename)
    if not m:
        return filename
    tag = m.group(3).lower()
    system = next((name for word, name in (("darwin", "macos"), ("win", "windows"), ("linux", "linux"))
                   if word in tag), "unknown")
    arch = next((name for word, name in (("arm64", "arm64"), ("aarch64", "arm64"), ("x86_64", "x64"),
                                         ("amd64", "x64")) if word in tag), "")
    return f"{system}{'-' + arch if arch else ''}, Python {m.group(1)}.{m.group(2)}"


@lru_cache(maxsize=None)
def problem(package: str) -> str:
    """'' when package._native imports, else a sentence for the user."""
    try:
        importlib.import_module(package + "._native")
        return ""
    except ImportError as exc:
        folder = os.path.dirname(importlib.import_module(package).__file__)
        builds = sorted(f for f in os.listdir(folder) if f.startswith("_native"))
        if not builds:
            return (f"Atlas Defrag cannot run: its native module is missing from {folder}. "
                    f"Install the add-on zip built for {running()}")
        have = "; ".join(built_for(f) for f in builds)
        return (f"Atlas Defrag cannot run here: its native module is built for {have}, and this Blender "
                f"is {running()}. Install the zip for {running().split(',')[0]} ({exc})")
