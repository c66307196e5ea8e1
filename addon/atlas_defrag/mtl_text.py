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


def unquoted(name: str) -> str:
    """A file name without the surrounding blanks and the double quotes some
    writers put round it for its spaces (in an MTL, and in a PLY's
    TextureFile comment; Blender reads both)."""
    name = name.strip()
    return name[1:-1] if len(name) >= 2 and name[0] == name[-1] == '"' else name


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


# The options that move, scale or jitter the UVs a map is read through, and
# their values that leave the UVs alone (a missing value keeps the default).
_UV_OPTION_IDENTITY = {"-o": 0.0, "-s": 1.0, "-t": 0.0}


def uv_transform(arguments: str) -> str:
    """The options of a map statement that change the UVs it reads through
    (-o, -s or -t with u or v values other than 0, 1 and 0), as written; ""
    when there is none."""
    words = arguments.split()
    found = []
    for i, word in enumerate(words[:-1]):  # the last word is the file
        identity = _UV_OPTION_IDENTITY.get(word.lower())
        if identity is None:
            continue
        values = []
        for value in words[i + 1:min(i + 4, len(words) - 1)]:
            if not _is_number(value):
                break
            values.append(value)
        if any(float(v) != identity for v in values[:2]):  # u and v (w moves nothing); NaN differs from all
            found.append(" ".join([word] + values))
    return " ".join(found)


def clamps(arguments: str) -> bool:
    """Whether a map statement's options say `-clamp on`: the texture is then
    read clamped to its edges, not repeated, where UVs leave [0, 1]."""
    words = [w.lower() for w in arguments.split()[:-1]]  # the last word is the file
    return any(w == "-clamp" and words[i + 1:i + 2] == ["on"] for i, w in enumerate(words))


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True
