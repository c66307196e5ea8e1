# SPDX-License-Identifier: MIT
"""The user options, listed once: every other place is generated from SCHEMA.

From this table come the operator's properties and dialog (operators.py), the
batch entry's arguments (batch.py), the validated values passed to the native
module (job.Options) and the option table of the README (tools/options_doc.py).
The native module checks the same ranges (python_tests/test_options.py).
Adding an option is one entry here, plus its use in the native core (or in
job.run, for options marked job).

No bpy and no numpy: batch.py loads this file by path outside Blender.
"""

from __future__ import annotations

import argparse
from typing import NamedTuple, Optional, Tuple


class Choice(NamedTuple):
    value: str  # as the native module takes it
    label: str
    help: str


class Option(NamedTuple):
    """One option. Numbers have a ``low`` bound; ``high`` None means none.
    Both are inclusive."""

    name: str  # keyword of job.Options and of the native module
    kind: type  # int, float, bool or str (one of choices)
    default: object
    label: str  # dialog label
    help: str
    low: Optional[float] = None
    high: Optional[float] = None
    choices: Tuple[Choice, ...] = ()
    # Set when 0 is allowed outside [low, high] and means "automatic": says
    # what automatic does. The dialog shows an Automatic toggle instead.
    automatic: str = ""
    manual_default: object = None  # the dialog's value when Automatic is off
    unit: str = ""  # 'texels' or ''
    bake: bool = False  # an option of _native.bake_maps, not of _native.defragment
    job: bool = False  # an option of job.run itself, passed to neither


SCHEMA: Tuple[Option, ...] = (
    Option("target_charts", int, 0, "Target Charts", "Number of charts to aim for",
           low=1, high=2 ** 31 - 1, automatic="no target: charts merge while the disk, curvature and size rules allow",
           manual_default=50),
    Option("weighting", str, "3d", "Weighting", "Seam length that decides which charts merge first",
           choices=(Choice("uv", "UV", "Merge by seam length measured in the texture"),
                    Choice("3d", "3D", "Merge by seam length measured on the surface"))),
    Option("density_loss_budget", float, 0.2, "Density Loss Budget",
           "Percent of the surface that may keep less than half its source texel density where flattening "
           "squeezes it (0: none; squeezed faces are repaired, and charts split or slit where that is not enough, "
           "for a few more charts and up to twice the layout time)",
           low=0.0, high=0.8),
    Option("padding", int, 4, "Padding", "Empty texels kept around every chart", low=0, high=64,
           unit="texels"),
    Option("padding_follows_page", bool, True, "Padding Follows Page Size",
           "Pages under 1024 texels get padding in proportion to their size, at least 2 texels: "
           "from the same distance a page half as large is read one mip level finer, "
           "so half the padding keeps the same distances free of bleeding"),
    Option("fixed_page_size", int, 0, "Page Size",
           "Side of one square output page, charts scaled as large as fit (at most Maximum Page Size, "
           "and a side Page Sides allows; Density Scale, Texels per Unit and Maximum Pages then do not apply)",
           low=64, high=16384, automatic="pages sized to keep the source texel budget",
           manual_default=4096, unit="texels"),
    Option("max_page_size", int, 8192, "Maximum Page Size", "Largest output page side",
           low=64, high=16384, unit="texels"),
    Option("density_scale", float, 1.0, "Density Scale",
           "Output texel density relative to the source (ignored with a fixed page size)",
           low=0.01, high=16.0),
    Option("texels_per_unit", float, 0.0, "Texels per Unit",
           "Output texel density in texels per unit of surface length (per metre in Blender, "
           "object scale included), "
           "instead of the source's density times Density Scale",
           low=0.001, high=1e9, automatic="the source's density times Density Scale", manual_default=1024.0),
    Option("max_pages", int, 0, "Maximum Pages",
           "Pages of Maximum Page Size the charts may fill before they are shrunk",
           low=1, high=4096, automatic="as many as the source uses, or as hold its texels",
           manual_default=1),
    Option("texels_at_most_input", bool, False, "At Most the Source's Texels",
           "Shrink the charts rather than exceed the source's texel count at the density asked for (times "
           "Density Scale squared, or as Texels per Unit gives it; costs detail on dense atlases; without it, "
           "a source whose faces share texels comes out larger, with a warning)"),
    Option("page_sides", str, "multiple_of_4", "Page Sides", "How the sides of each output page are rounded",
           choices=(Choice("tight", "Tight", "The smallest page that holds the charts"),
                    Choice("multiple_of_4", "Multiple of 4", "Sides a multiple of 4 texels (BCn and ASTC blocks)"),
                    Choice("power_of_two", "Power of Two", "Sides a power of two (older engines, full mip chains)"))),
    Option("square_pages", bool, False, "Square Pages", "Both sides of every page equal (the larger one)"),
    Option("packing_cut_seam", float, 0.0, "Seam for Tighter Packing",
           "Seam the packer may add by cutting charts that pack poorly in two, as 3D length / sqrt(surface "
           "area), the unit of the seam figure (0: no cut): fewer texels for more seams and charts",
           low=0.0, high=10.0),
    Option("fit_cut_seam", float, 1.0, "Seam to Stay Within the Source",
           "When the charts would take over 1.1 times the source's texels at the density asked for, or be "
           "shrunk to fit, charts that pack poorly are cut in two until this much seam in all (the unit of Seam "
           "for Tighter Packing; 0: never): dense atlases keep about their size for a little more seam",
           low=0.0, high=10.0),
    Option("padding_between_charts", bool, False, "Padding Between Charts",
           "Padding is the gap between two charts (as in xatlas) rather than a ring around each chart "
           "(charts twice the padding apart); packs tighter, keeps one mip level fewer clean"),
    Option("fit_texels", bool, False, "Fit Texels",
           "Texels chosen by least squares so that the new texture, read bilinearly as renderers read it, "
           "matches the old one read the same way: a little sharper, for a bake two to three times as long "
           "(off: each texel samples the old texture at its centre). Normal maps are sampled either way",
           bake=True),
    Option("min_colour_psnr", float, 40.0, "Least Colour PSNR",
           "When the new base colour matches the old one less closely than this (PSNR in dB over the surface), "
           "as on sharp textures, the job runs again at 1.25, 1.5 or 2 times the texel density, as long as the "
           "pages stay as many and within the source's texels at the density asked for (0: never; not with a "
           "Density Scale below 1, a fixed page size or Texels per Unit)",
           low=0.0, high=99.0, job=True),
)

BY_NAME = {o.name: o for o in SCHEMA}


def range_text(option: Option) -> str:
    """The allowed values in words, as error messages and docs say them."""
    if option.choices:
        return " or ".join(repr(c.value) for c in option.choices)
    if option.kind is bool:
        return "True or False"
    if option.high is None:
        text = f">= {option.low}"
    else:
        text = f"{option.low}..{option.high}"
    return f"0 (automatic) or {text}" if option.automatic else text


def check(option: Option, value):
    """value converted to the option's type; ValueError naming the option and
    its range when it is outside. A numpy scalar counts as the Python value
    it holds (np.float32(0.8) is 0.800000011920929)."""
    if hasattr(value, "item") and getattr(value, "ndim", None) == 0:
        value = value.item()
    if option.choices:
        text = str(value).lower()
        if text not in {c.value for c in option.choices}:
            raise ValueError(f"{option.name} must be {range_text(option)}, not {value!r}")
        return text
    if option.kind is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{option.name} must be {range_text(option)}, not {value!r}")
        return value
    number = _number(option, value)
    if number is None:
        kind = "an integer" if option.kind is int else "a number"
        raise ValueError(f"{option.name} must be {kind} {range_text(option)}, not {value!r}")
    if option.automatic and number == 0:
        return number
    if not _within(option, number):
        raise ValueError(f"{option.name} must be {range_text(option)}, not {value!r}")
    return number


def _number(option: Option, value):
    """value as the option's kind, or None (text that is no number, 2.5 for an int)."""
    try:
        number = option.kind(value)
        exact = option.kind is float or float(value) == number
    except (TypeError, ValueError, OverflowError):  # OverflowError: an infinity for an int
        return None
    return number if exact else None


def _within(option: Option, number) -> bool:
    low_ok = option.low is None or number >= option.low
    return low_ok and (option.high is None or number <= option.high)


def validate(values: dict) -> dict:
    """Every option checked, and the one rule between two of them."""
    out = {name: check(BY_NAME[name], value) for name, value in values.items()}
    fixed = out.get("fixed_page_size", 0)
    largest = out.get("max_page_size", BY_NAME["max_page_size"].default)
    if fixed > largest:
        raise ValueError(f"fixed_page_size {fixed} is larger than max_page_size {largest}")
    sides = out.get("page_sides", BY_NAME["page_sides"].default)
    if fixed and not {"multiple_of_4": fixed % 4 == 0, "power_of_two": fixed & (fixed - 1) == 0}.get(sides, True):
        raise ValueError(f"fixed_page_size {fixed} is not a side page_sides {sides} allows")
    return out


def flag(option: Option) -> str:
    return "--" + option.name.replace("_", "-")


def argument_words(option: Option, value) -> list:
    """The command-line words that give option this value (add_arguments parses them back)."""
    if option.kind is bool:
        return [flag(option) if value else "--no-" + flag(option)[2:]]
    return [flag(option), str(value)]


def add_arguments(group) -> None:
    """Every option as a command-line flag of an argparse parser or group
    (the batch entry, tools/defrag_scan.py); bad values exit with code 2."""
    for o in SCHEMA:
        if o.kind is bool:
            group.add_argument(flag(o), action=argparse.BooleanOptionalAction, default=o.default,
                               help=f"{o.help} (default {o.default!r})")
            continue
        zero = f"; 0: {o.automatic}" if o.automatic else ""
        group.add_argument(flag(o), type=_argument_type(o), default=o.default,
                           metavar=None if o.choices else o.name.upper(),
                           choices=[c.value for c in o.choices] or None,
                           help=f"{o.help} ({range_text(o)}, default {o.default!r}{zero})")


def parsed(parser, argv):
    """parser.parse_args(argv), with the rule between two options checked
    there too: a bad pair exits with code 2 before any work, as a bad value does."""
    args = parser.parse_args(argv)
    try:
        validate({o.name: getattr(args, o.name) for o in SCHEMA if hasattr(args, o.name)})
    except ValueError as exc:
        parser.error(str(exc))
    return args


def _argument_type(option: Option):
    def parse(text):
        try:
            return check(option, text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from exc
    parse.__name__ = option.name  # argparse names the type in some messages
    return parse
