"""The layout of a scan stored at other tessellations, as scanners export one
surface at 50k or 500k faces.

    .venv/bin/python bench/tessellation.py                        # this checkout's build
    .venv/bin/python bench/tessellation.py --addon OTHER/build/addon --out /tmp/base.md

Each shared scan goes through `_native.defragment` as it is, with every
triangle split in four (tools/scan_variants.split_in_four: the same surface
and atlas), and split in four with 300 loose triangles added (debris, as
phone scans keep); the Meshroom scan also split in four twice. Each variant
runs with the default options and with `reference_chart_faces` 0 (the
aggregation's face counts not scaled with the tessellation, as before
session 39). Charts and seam (3D length / sqrt(area)) for both; for the
default, flips, texels covered twice and the share of the surface below
half its texel density by _native.measure, and colour PSNR by
_native.compare_colors (200k points) against the scan's atlas. Seconds: the
layout's native stages summed, one run each. Writes bench/TESSELLATION.md
(or --out). Not part of the test suite (about three minutes).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from holes import measured, run_table  # beside this file

HERE = Path(__file__).resolve().parent
DEBRIS = 300


def variants(name: str, scan) -> dict:
    """Label -> (positions, triangles, uvs, face_page, page_sizes)."""
    from scan_variants import split_in_four, with_debris

    base = (scan.positions, scan.triangles, scan.uvs)
    four = split_in_four(*base)
    out = {"as it is": base + (scan.face_page,), "split in four": four + (np.repeat(scan.face_page, 4),)}
    out[f"split in four, {DEBRIS} loose triangles"] = with_debris(*out["split in four"], DEBRIS)
    if name == "meshroom":
        out["split in four twice"] = split_in_four(*four) + (np.repeat(scan.face_page, 16),)
    return {label: arrays + (scan.page_sizes,) for label, arrays in out.items()}


def row(native, label: str, before: tuple, pages: list) -> str:
    old = native.defragment(*before, options={"reference_chart_faces": 0})["report"]
    result = native.defragment(*before)
    r = result["report"]
    m, psnr = measured(native, before, pages, result)
    return (f"| {label} | {len(before[1]):,} | {old['charts_after']} | {old['seam_after']:.2f} | "
            f"{sum(old['seconds'].values()):.2f} | {r['charts_after']} | {r['seam_after']:.2f} | "
            f"{m['new']['flipped_faces']} | {m['new']['overlap_texels']} | "
            f"{100 * m['map']['density_loss_area_share']:.2f}% | {psnr:.1f} | {sum(r['seconds'].values()):.2f} |")


def main(argv=None) -> int:
    header = ["variant", "faces", "unscaled: charts", "seam", "s", "default: charts", "seam", "flips",
              "texels twice", "below half density", "PSNR dB", "s"]
    return run_table(argv, __doc__, HERE / "TESSELLATION.md", "One surface at other tessellations",
                     "*Unscaled*: `reference_chart_faces` 0, the aggregation's face counts as they are; *default*: "
                     "scaled with the faces per input chart. Charts count the loose triangles, one chart each.",
                     header, lambda native, name, scan, pages: (row(native, label, before, pages)
                                                                for label, before in variants(name, scan).items()))


if __name__ == "__main__":
    sys.exit(main())
