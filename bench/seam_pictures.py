"""Seams drawn on the model, before and after: the input's UV seams and Atlas Defrag's.

    .venv/bin/python bench/seam_pictures.py [--model meshroom|smithsonian|tetra] [--size 720] [--both-sides]

Runs the numpy path's layout (_native.defragment, default options; no bake is
needed to draw seams), then renders the mesh along its thinnest principal axis (and from the
other side too with --both-sides, for closed scans), flat shaded grey, with every edge whose two faces disagree in UV drawn in colour.
Writes bench/pictures/<model>_seams.png. A separate script from
run_benchmark.py, whose run takes ten minutes: this one takes seconds.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build"))
sys.path.insert(0, str(BUILD / "addon"))  # the package imports bpy only inside Blender
sys.path.insert(0, str(REPO / "tools"))
sys.path.insert(0, str(HERE))

from atlas_defrag import _native  # noqa: E402  (scan_io reads OBJ through the same module)
import scan_io  # noqa: E402
from run_benchmark import MODELS, _chart_boundary_edges, _sheet  # noqa: E402


def interior_seams(scan, uvs, face_page) -> np.ndarray:
    """(F, 3) flags: corner edge on a UV seam between two faces (mesh borders left out)."""
    seam = _chart_boundary_edges(scan, uvs, face_page)
    _, weld = np.unique(np.round(scan.positions, 9), axis=0, return_inverse=True)
    tri = weld.reshape(-1)[scan.triangles]
    a, b = tri, np.roll(tri, -1, axis=1)
    key = (np.minimum(a, b).astype(np.int64) * (tri.max() + 1) + np.maximum(a, b)).reshape(-1)
    _, inverse, count = np.unique(key, return_inverse=True, return_counts=True)
    return seam & (count[inverse].reshape(-1, 3) >= 2)


def view_frame(positions: np.ndarray) -> np.ndarray:
    """Rows: screen x, screen y, depth; principal axes, depth along the thinnest."""
    centred = positions - positions.mean(0)
    _, _, axes = np.linalg.svd(centred[:: max(1, len(centred) // 20000)], full_matrices=False)
    frame = axes.copy()
    if np.linalg.det(frame) < 0:
        frame[2] = -frame[2]
    return frame


def render(scan, seams: np.ndarray, frame: np.ndarray, size: int, colour) -> "Image":
    """Painter's algorithm: faces far to near, lit by their normal; a seam edge is drawn
    where the face-id buffer shows one of its faces at the edge's midpoint."""
    from PIL import Image, ImageDraw
    p = (scan.positions - scan.positions.mean(0)) @ frame.T
    lo, hi = p[:, :2].min(0), p[:, :2].max(0)
    scale = 0.92 * size / (hi - lo).max()
    xy = (p[:, :2] - (lo + hi) / 2) * scale + size / 2
    xy[:, 1] = size - xy[:, 1]
    corners = xy[scan.triangles]
    normal = np.cross(p[scan.triangles[:, 1]] - p[scan.triangles[:, 0]], p[scan.triangles[:, 2]] - p[scan.triangles[:, 0]])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
    # Depth grows towards the viewer (+z): draw the smallest first.
    order = np.argsort(p[scan.triangles][:, :, 2].mean(1))
    shade = (60 + 170 * np.abs(normal[:, 2])).astype(int)
    image = Image.new("RGB", (size, size), (24, 24, 24))
    ids = Image.new("RGB", (size, size), (0, 0, 0))
    draw, draw_ids = ImageDraw.Draw(image), ImageDraw.Draw(ids)
    for f in order.tolist():
        tri = [tuple(c) for c in corners[f].tolist()]
        g = int(shade[f])
        draw.polygon(tri, fill=(g, g, g))
        n = f + 1
        draw_ids.polygon(tri, fill=(n & 255, (n >> 8) & 255, (n >> 16) & 255))
    buffer = np.asarray(ids).astype(np.int64)
    visible_face = buffer[..., 0] + (buffer[..., 1] << 8) + (buffer[..., 2] << 16) - 1
    for f, k in zip(*np.nonzero(seams)):
        a, b = corners[f, k], corners[f, (k + 1) % 3]
        inward = corners[f].mean(0) - (a + b) / 2
        probe = (a + b) / 2 + 1.5 * inward / max(np.linalg.norm(inward), 1e-9)
        x, y = int(round(probe[0])), int(round(probe[1]))
        if 0 <= x < size and 0 <= y < size and visible_face[y, x] == f:
            draw.line([tuple(a), tuple(b)], fill=colour, width=2)
    return image


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", choices=[m for m, p in MODELS.items() if p], default="meshroom")
    parser.add_argument("--size", type=int, default=720)
    parser.add_argument("--out", type=Path, default=HERE / "pictures")
    parser.add_argument("--both-sides", action="store_true")
    parser.add_argument("--tag", default="", help="names the picture <model>_seams_<tag>.png and the layout "
                        "'Atlas Defrag (<tag>)': for a module built from another commit (ATLAS_BUILD_DIR)")
    args = parser.parse_args(argv)
    scan = scan_io.load(MODELS[args.model])
    result = _native.defragment(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                                options={"padding": 4})
    r = result["report"]
    before = interior_seams(scan, scan.uvs, scan.face_page)
    after = interior_seams(scan, result["uvs"], result["face_page"])
    frame = view_frame(scan.positions)
    back = frame * np.array([[-1], [1], [-1]])  # turned half round the screen's y axis
    panels, captions = [], []
    for name, seams, charts, seam, colour in (
            ("input", before, r["charts_before"], r["seam_before"], (255, 90, 60)),
            ("Atlas Defrag" + (f" ({args.tag})" if args.tag else ""), after, r["charts_after"], r["seam_after"], (255, 220, 0))):
        for side, f in (("front", frame), ("back", back))[:2 if args.both_sides else 1]:
            panels.append(render(scan, seams, f, args.size, colour))
            captions.append(f"{name}, {side}: {charts} charts, seam {seam:.1f}")
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"{args.model}_seams{'_' + args.tag if args.tag else ''}.png"
    _sheet(panels, captions, path, f"{args.model}: UV seams drawn on the model (seam = 3D length / sqrt(area))")
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
