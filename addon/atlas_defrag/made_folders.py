# SPDX-License-Identifier: MIT
"""The folders a write makes for its files, and taking them back when the
write fails (a full disk), so that a failed run leaves no empty folders.
bpy-free: the add-on's writer and the command-line entry share it."""

from __future__ import annotations

import os
from typing import List


def missing(path) -> List[str]:
    """The folders os.makedirs(path) would make, deepest first."""
    path, made = os.fspath(path), []
    while path and not os.path.isdir(path) and path != os.path.dirname(path):
        made.append(path)
        path = os.path.dirname(path)
    return made


def remove_empty(folders: List[str]) -> None:
    """Removes the folders (deepest first) as long as each is empty."""
    for folder in folders:
        try:
            os.rmdir(folder)
        except OSError:
            return
