# SPDX-License-Identifier: MIT
"""What the statements of an MTL file name (no bpy): the batch entry checks
the MTL Blender wrote, the command-line reader resolves a scan's textures."""

from __future__ import annotations

import re

# Options of an MTL map statement and how many words follow each; -o, -s and
# -t take one to three numbers.
_MAP_OPTION_WORDS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
                     "-mm": 2, "-texres": 1, "-type": 1, "-o": 3, "-s": 3, "-t": 3}
# Statements that name an image file.
MAP_STATEMENTS = ("map_", "bump", "disp", "norm", "refl")


def map_file(arguments: str) -> str:
    """The file a map statement names: its arguments after the options (a
    file name may hold spaces)."""
    words = list(re.finditer(r"\S+", arguments))
    i = 0
    while i < len(words) - 1 and words[i].group().lower() in _MAP_OPTION_WORDS:
        option = words[i].group().lower()
        i += 1
        for _ in range(_MAP_OPTION_WORDS[option]):
            if i >= len(words) - 1 or (option in ("-o", "-s", "-t") and not _is_number(words[i].group())):
                break
            i += 1
    return arguments[words[i].start():].strip() if i < len(words) else ""


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True
