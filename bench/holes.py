"""The job on scans with holes, as phone LiDAR and photogrammetry leave them.

    .venv/bin/python bench/holes.py                        # this checkout's build
    .venv/bin/python bench/holes.py --addon OTHER/build/addon --out /tmp/base.md

Each shared scan goes through `_native.defragment` (default options) as it
is, and with holes made in it: faces chosen at random (seed 1) taken out,
each alone (a hole of three edges) or with the faces around it (`ring` 1:
every face sharing a vertex with it, a hole of about a dozen edges). Charts,
seam (3D length / sqrt(area)), flips, texels covered twice and the share of
the surface below half its texel density by _native.measure; colour PSNR by
_native.compare_colors (200k points) against the scan's atlas; the layout's
seconds (the native stages summed) and the holes filled from the job's report. Writes bench/HOLES.md
(or --out). Not part of the test suite (about a minute).
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
    "meshroom": "meshroom_esp32cam/texturedMesh.obj",
    "smithsonian": "smithsonian_usnm1145291/usnm_1145291.glb",
    "tetra": "tetra_miniature/teTra-Mk5-miniature-model.obj",
}
VARIANTS = [(0, 0), (100, 0), (300, 0), (100, 1), (300, 1)]  # (holes, ring)


def without_holes(scan, holes: int, ring: int) -> np.ndarray:
    """Faces kept once `holes` faces chosen at random, and `ring` rings of faces around each, are taken out."""
    faces = len(scan.triangles)
    drop = np.zeros(faces, bool)
    drop[np.random.default_rng(1).choice(faces, holes, replace=False)] = True
    for _ in range(ring):
        touched = np.zeros(len(scan.positions), bool)
        touched[scan.triangles[drop].ravel()] = True
        drop |= touched[scan.triangles].any(axis=1)
    return ~drop


def measured(native, before: tuple, pages: list, result: dict) -> tuple:
    """(_native.measure of a defragment result, its colour PSNR on 200k points
    against the scan's atlas). before: the defragment call's arrays."""
    m = native.measure(*before, result["uvs"], result["face_page"], result["page_sizes"])
    new = native.bake(before[2], before[3], pages, result["uvs"], result["face_page"], result["page_sizes"])
    psnr = native.compare_colors(before[0], before[1], before[2], before[3], pages, result["uvs"],
                                 result["face_page"], new, samples=200000)["psnr_db"]
    return m, psnr


def row(native, scan, pages, holes: int, ring: int) -> str:
    keep = without_holes(scan, holes, ring)
    before = (scan.positions, scan.triangles[keep], scan.uvs[keep], scan.face_page[keep], scan.page_sizes)
    result = native.defragment(*before)
    m, psnr = measured(native, before, pages, result)
    r = result["report"]
    return (f"| {holes} | {ring} | {int((~keep).sum()):,} | {m['old']['charts']:,} -> {m['new']['charts']} | "
            f"{m['old']['seam_ratio']:.1f} -> {m['new']['seam_ratio']:.2f} | {r['aggregate_stops']['not_disk']} | "
            f"{r.get('holes_filled', '-')} | {m['new']['flipped_faces']} | {m['new']['overlap_texels']} | "
            f"{100 * m['map']['density_loss_area_share']:.2f}% | {psnr:.1f} | {sum(r['seconds'].values()):.2f} |")


def run_table(argv, doc: str, out: Path, title: str, intro: str, header: list, scan_rows) -> int:
    """The command line this script and tessellation.py share: --addon (the
    package to measure) and --out; one table of `header` columns, a bold row
    per scan and then the rows scan_rows(native, name, scan, pages) yields."""
    p = argparse.ArgumentParser(description=doc.split("\n")[0])
    p.add_argument("--addon", default=str(REPO / "build" / "addon"), help="folder holding the atlas_defrag package")
    p.add_argument("--out", default=str(out))
    args = p.parse_args(argv)
    sys.path[:0] = [args.addon, str(REPO / "tools")]
    import scan_io
    from atlas_defrag import _native
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    lines = [f"# {title}", "", f"`bench/{out.stem.lower()}.py`, {datetime.datetime.now():%Y-%m-%d %H:%M}, commit "
             f"`{commit}`, module from `{args.addon}`. {intro}", "",
             "| " + " | ".join(header) + " |", "|" + "---:|" * len(header)]
    for name, path in SCANS.items():
        scan = scan_io.load(MODELS / path)
        pages = [np.ascontiguousarray(scan_io.load_image(q)[:, :, :3]) for q in scan.page_images]
        lines.append(f"| **{name}** |" + " |" * (len(header) - 1))
        for line in scan_rows(_native, name, scan, pages):
            lines.append(line)
            print(line, flush=True)
    Path(args.out).write_text("\n".join(lines) + "\n")
    return 0


def main(argv=None) -> int:
    header = ["holes", "ring", "faces out", "charts", "seam", "not_disk stops", "holes filled", "flips",
              "texels twice", "below half density", "PSNR dB", "layout s"]
    return run_table(argv, __doc__, HERE / "HOLES.md", "Scans with holes",
                     "Holes: faces chosen at random (seed 1) taken out, with `ring` rings of faces around each; "
                     "default options otherwise.", header,
                     lambda native, name, scan, pages: (row(native, scan, pages, h, r) for h, r in VARIANTS))


if __name__ == "__main__":
    sys.exit(main())
