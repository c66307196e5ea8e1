"""The job on atlases it was not tuned on: the three scans charted again two other ways.

    PYTHONPATH=build/addon .venv/bin/python bench/rechart.py

Each scan's texture is baked (_native.bake) onto a new atlas of the same
mesh, which then goes through the job with default options (_native.defragment,
then _native.bake), as the command-line entry runs it:
  * one face per chart: every triangle at its 3D shape, at the scan's median
    texel density, in rows on one page (the most fragmented atlas there is;
    some phone apps texture per face);
  * xatlas (PyPI bindings, default options): an unwrapper's charts, fewer and
    flatter than a photogrammetry atlas's.
Beside each, the figures of the scan's own atlas. Charts, seam (3D length /
sqrt(area)), flips, texels covered twice and density loss by _native.measure;
PSNR by _native.compare_colors (200k points) against the atlas the job read.
Writes bench/RECHART.md. Not part of the test suite (about 2 min).
"""
from __future__ import annotations

import datetime
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path[:0] = [str(REPO / "build" / "addon"), str(REPO / "tools")]

import scan_io  # noqa: E402
from atlas_defrag import _native, job  # noqa: E402

MODELS = REPO.parent / "shared" / "models"
SCANS = {
    "meshroom": "meshroom_esp32cam/texturedMesh.obj",
    "smithsonian": "smithsonian_usnm1145291/usnm_1145291.glb",
    "tetra": "tetra_miniature/teTra-Mk5-miniature-model.obj",
}
GAP = 2  # texels between two faces of the one-face-per-chart atlas


def face_frames(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(F, 3, 2) every triangle in its own plane, isometric, its box at the origin."""
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    x = b - a
    normal = np.cross(x, c - a)
    x /= np.maximum(np.linalg.norm(x, axis=1), 1e-300)[:, None]
    y = np.cross(normal / np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None], x)
    local = np.stack([np.zeros((len(a), 2)), np.stack([((b - a) * x).sum(1), np.zeros(len(a))], 1),
                      np.stack([((c - a) * x).sum(1), ((c - a) * y).sum(1)], 1)], axis=1)
    return local - local.min(axis=1, keepdims=True)


def texel_density(scan) -> float:
    """Median texels per unit length of the scan's own atlas, over textured faces."""
    p, t = scan.positions, scan.triangles
    area_3d = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    uv = scan.uvs * scan.page_sizes[np.maximum(scan.face_page, 0)][:, None, :]
    area_uv = 0.5 * np.abs(np.cross(uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]))
    ok = (scan.face_page >= 0) & (area_3d > 0) & (area_uv > 0)
    return float(np.sqrt(np.median(area_uv[ok] / area_3d[ok])))


def one_face_per_chart(scan):
    """(corner UVs (F, 3, 2) in page units, page size) of the one-face-per-chart atlas."""
    local = face_frames(scan.positions, scan.triangles) * texel_density(scan)
    cell = local.max(axis=1) + GAP
    side = int(np.ceil(np.sqrt(cell.prod(axis=1).sum() * 1.3)))
    offset = np.zeros((len(cell), 2))
    x = y = row = 0.0
    for f in np.argsort(-cell[:, 1], kind="stable"):  # rows of faces, tallest first
        if x + cell[f, 0] > side:
            x, y, row = 0.0, y + row, 0.0
        offset[f] = (x + GAP / 2, y + GAP / 2)
        x, row = x + cell[f, 0], max(row, cell[f, 1])
    size = np.array([side, int(np.ceil(y + row))])
    return (local + offset[:, None, :]) / size, size


def xatlas_charts(scan):
    """(corner UVs (F, 3, 2) in page units, page size) of xatlas's atlas of the mesh."""
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(scan.positions.astype(np.float32), scan.triangles.astype(np.uint32))
    atlas.generate()
    vmapping, indices, uvs = atlas[0]
    if not np.array_equal(vmapping[indices], scan.triangles):
        raise SystemExit("xatlas reordered the faces")
    return uvs[indices].astype(np.float64), np.array([atlas.width, atlas.height])


def run(scan, uvs, size) -> dict:
    """The job on the re-charted scan, measured against that atlas."""
    old = [scan_io.load_image(p)[:, :, :3].copy() for p in scan.page_images[:1]]
    textured = np.where(scan.face_page == 0, 0, -1).astype(np.int32)
    sizes = np.array([size], np.int32)
    page = _native.bake(scan.uvs, scan.face_page, old, uvs, textured, sizes)
    t = time.perf_counter()
    out = _native.defragment(scan.positions, scan.triangles, uvs, textured, sizes,
                             options=job.Options().native())
    new = _native.bake(uvs, textured, page, out["uvs"], out["face_page"], out["page_sizes"])
    seconds = time.perf_counter() - t
    m = _native.measure(scan.positions, scan.triangles, uvs, textured, sizes,
                        out["uvs"], out["face_page"], out["page_sizes"])
    c = _native.compare_colors(scan.positions, scan.triangles, uvs, textured, page,
                               out["uvs"], out["face_page"], new, samples=200000)
    r = out["report"]
    return {"charts": (r["charts_before"], r["charts_after"]), "seam": (r["seam_before"], r["seam_after"]),
            "flips": m["new"]["flipped_faces"], "twice": m["new"]["overlap_texels"],
            "loss": m["map"]["density_loss_area_share"], "psnr": c["psnr_db"],
            "texels": (int(np.prod(size)), r["texels_after"]), "seconds": seconds}


def row(scan_name: str, atlas: str, f: dict) -> str:
    return (f"| {scan_name} | {atlas} | {f['charts'][0]:,} -> {f['charts'][1]:,} | {f['seam'][0]:.1f} -> "
            f"{f['seam'][1]:.1f} | {f['flips']} | {f['twice']} | {100 * f['loss']:.2f}% | {f['psnr']:.1f} | "
            f"{f['texels'][0]:,} -> {f['texels'][1]:,} | {f['seconds']:.2f} |")


def main() -> None:
    lines = []
    for name, rel in SCANS.items():
        scan = scan_io.load(MODELS / rel)
        own = run(scan, scan.uvs, scan.page_sizes[0]) if len(scan.page_sizes) == 1 else None
        for atlas, make in (("its own", None), ("one face per chart", one_face_per_chart), ("xatlas", xatlas_charts)):
            figures = own if make is None else run(scan, *make(scan))
            lines.append(row(name, atlas, figures))
            print(lines[-1], flush=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                            text=True).stdout.strip()
    head = __doc__.split("\n\n", 2)[2].split("Writes")[0].strip()
    text = (f"# The job on atlases made again\n\n`bench/rechart.py`, "
            f"{datetime.datetime.now():%Y-%m-%d %H:%M}, commit `{commit}`, default options.\n\n{head}\n\n"
            "| scan | atlas | charts | seam | flips | texels covered twice | density loss | PSNR (dB) | texels | "
            "seconds |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n" + "\n".join(lines) + "\n")
    (HERE / "RECHART.md").write_text(text)


if __name__ == "__main__":
    main()
