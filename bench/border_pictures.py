"""Pictures of what the bake does at old chart borders (gutter bleed).

    .venv/bin/python bench/border_pictures.py [--scan smithsonian] [--crops 4]

Defragments one scan, bakes its base colour, then bakes the result back into
the old layout with the same code, so that old and new colours of the same
surface points sit texel by texel side by side. For the old chart-border texels
of large charts where the two differ most, writes bench/pictures/border_<scan>.png: per crop
(24 x 24 old texels, magnified 8x) the old atlas, the new atlas seen through the
old layout, and their difference x4, with old chart borders drawn in red and
old gutter texels (no old chart covers their centre) darkened. Not a test.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build"))
sys.path.insert(0, str(BUILD / "addon"))  # the package imports bpy only inside Blender
sys.path.insert(0, str(REPO / "tools"))
sys.path.insert(0, str(REPO / "python_tests"))

from atlas_defrag import _native  # noqa: E402  (scan_io reads OBJ through the same module)
import scan_io  # noqa: E402

SCANS = {
    "meshroom": "meshroom_esp32cam/texturedMesh.obj",
    "smithsonian": "smithsonian_usnm1145291/usnm_1145291.glb",
    "tetra": "tetra_miniature/teTra-Mk5-miniature-model.obj",
}
CROP, ZOOM = 24, 8


def chart_owner(scan, page: int, size) -> np.ndarray:
    """Old chart per texel centre of one page (-1: none, -2: several), by rasterising faces."""
    from PIL import Image, ImageDraw

    graph = _native.chart_graph(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes)
    w, h = int(size[0]), int(size[1])
    owner = np.full((h, w), -1, np.int64)
    faces = np.nonzero(scan.face_page == page)[0]
    chart = graph["face_chart"][faces]
    for c in np.unique(chart):
        im = Image.new("1", (w, h))
        draw = ImageDraw.Draw(im)
        for f in faces[chart == c]:
            draw.polygon([(u * w - 0.5, v * h - 0.5) for u, v in scan.uvs[f]], fill=1)
        mask = np.asarray(im, bool)
        owner[mask & (owner == -1)] = c
        owner[mask & (owner >= 0) & (owner != c)] = -2
    return owner


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scan", choices=sorted(SCANS), default="smithsonian")
    parser.add_argument("--crops", type=int, default=4)
    parser.add_argument("--models", type=Path, default=REPO.parent / "shared" / "models")
    args = parser.parse_args()
    from PIL import Image

    scan = scan_io.load(args.models / SCANS[args.scan])
    old = [np.ascontiguousarray(scan_io.load_image(p["base_color"])[:, :, :3]) for p in scan.maps]
    result = _native.defragment(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes)
    new = _native.bake(scan.uvs, scan.face_page, old, result["uvs"], result["face_page"], result["page_sizes"])
    back = _native.bake(result["uvs"], result["face_page"], new, scan.uvs, scan.face_page, scan.page_sizes)
    page = 0
    owner = chart_owner(scan, page, scan.page_sizes[page])
    # Border texels: inside a chart, with a 4-neighbour outside it.
    inside = owner >= 0
    border = np.zeros_like(inside)
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        border |= inside & (np.roll(owner, (dy, dx), (0, 1)) != owner)
    diff = np.abs(old[page].astype(int) - back[page].astype(int)).max(axis=2)
    h, w = owner.shape
    # Crops on the borders of large charts (debris charts of a few texels are
    # all border), at the texels that differ most.
    counts = np.bincount(owner[inside])
    large = inside & (counts[np.maximum(owner, 0)] >= 5000)
    ys, xs = np.nonzero(border & large & (diff > 0))
    order = np.argsort(-diff[ys, xs])
    picked = []
    for i in order:
        y, x = ys[i], xs[i]
        if CROP <= y < h - CROP and CROP <= x < w - CROP and all(abs(y - py) + abs(x - px) > 2 * CROP for py, px in picked):
            picked.append((y, x))
        if len(picked) == args.crops:
            break
    rows = []
    for y, x in picked:
        sl = (slice(y - CROP // 2, y + CROP // 2), slice(x - CROP // 2, x + CROP // 2))
        own = owner[sl]
        edge = np.zeros(own.shape, bool)
        for dy, dx in ((0, 1), (1, 0)):
            edge |= own != np.roll(own, (dy, dx), (0, 1))
        panels = []
        for image in (old[page][sl], back[page][sl], np.clip(4 * np.abs(old[page][sl].astype(int) - back[page][sl].astype(int)), 0, 255)):
            p = image.astype(float)
            p[own < 0] *= 0.5
            p[edge] = (255, 0, 0)
            panels.append(np.kron(p[::-1].astype(np.uint8), np.ones((ZOOM, ZOOM, 1), np.uint8)))
        rows.append(np.concatenate([np.concatenate([pnl, np.full((pnl.shape[0], 4, 3), 255, np.uint8)], 1) for pnl in panels], 1))
    out = REPO / "bench" / "pictures" / f"border_{args.scan}.png"
    Image.fromarray(np.concatenate([np.concatenate([r, np.full((4, r.shape[1], 3), 255, np.uint8)], 0) for r in rows], 0)).save(out)
    print(f"{out}: {len(picked)} crops; {border.sum():,} border texels, {np.mean(diff[border] > 8):.1%} of them off by > 8/255 "
          f"({np.mean(diff[inside & ~border] > 8):.2%} of the interior)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
