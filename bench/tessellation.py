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

import argparse
import datetime
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
MODELS = REPO.parent / "shared" / "models"
SCANS = {
    "tetra": "tetra_miniature/teTra-Mk5-miniature-model.obj",
    "meshroom": "meshroom_esp32cam/texturedMesh.obj",
    "smithsonian": "smithsonian_usnm1145291/usnm_1145291.glb",
}
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
    m = native.measure(*before, result["uvs"], result["face_page"], result["page_sizes"])
    new = native.bake(before[2], before[3], pages, result["uvs"], result["face_page"], result["page_sizes"])
    psnr = native.compare_colors(before[0], before[1], before[2], before[3], pages, result["uvs"],
                                 result["face_page"], new, samples=200000)["psnr_db"]
    return (f"| {label} | {len(before[1]):,} | {old['charts_after']} | {old['seam_after']:.2f} | "
            f"{sum(old['seconds'].values()):.2f} | {r['charts_after']} | {r['seam_after']:.2f} | "
            f"{m['new']['flipped_faces']} | {m['new']['overlap_texels']} | "
            f"{100 * m['map']['density_loss_area_share']:.2f}% | {psnr:.1f} | {sum(r['seconds'].values()):.2f} |")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--addon", default=str(REPO / "build" / "addon"), help="folder holding the atlas_defrag package")
    p.add_argument("--out", default=str(HERE / "TESSELLATION.md"))
    args = p.parse_args(argv)
    sys.path[:0] = [args.addon, str(REPO / "tools")]
    import scan_io
    from atlas_defrag import _native
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    lines = ["# One surface at other tessellations", "",
             f"`bench/tessellation.py`, {datetime.datetime.now():%Y-%m-%d %H:%M}, commit `{commit}`, module from "
             f"`{args.addon}`. *Unscaled*: `reference_chart_faces` 0, the aggregation's face counts as they are; "
             "*default*: scaled with the faces per input chart. Charts count the loose triangles, one chart each.",
             "", "| variant | faces | unscaled: charts | seam | s | default: charts | seam | flips | texels twice | "
             "below half density | PSNR dB | s |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, path in SCANS.items():
        scan = scan_io.load(MODELS / path)
        pages = [np.ascontiguousarray(scan_io.load_image(q)[:, :, :3]) for q in scan.page_images]
        lines.append(f"| **{name}** | | | | | | | | | | | |")
        for label, before in variants(name, scan).items():
            lines.append(row(_native, label, before, pages))
            print(lines[-1], flush=True)
    Path(args.out).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
