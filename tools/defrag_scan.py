"""Defragments a scan's atlas without Blender and prints what changed.

    .venv/bin/python tools/defrag_scan.py IN.obj|IN.glb OUT_DIR [--padding 4] [--target-charts N]

Writes OUT_DIR/<name>.obj + .mtl + one PNG per page and map, and prints charts,
seam length, texels, PSNR and seconds per stage. The Blender add-on does the
same through bpy; this entry exists for machines and pipelines without it.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build"))  # as python_tests/conftest.py
# The module alone, not the add-on package: its __init__ would import bpy.
sys.path.insert(0, str(BUILD / "addon" / "atlas_defrag"))
sys.path.insert(0, str(REPO / "tools"))

import _native  # noqa: E402
import png_files  # noqa: E402
import scan_io  # noqa: E402


def progress_line(stage: str, fraction: float) -> None:
    """One self-overwriting status line, on terminals only (logs stay clean)."""
    if sys.stderr.isatty():
        print(f"\r  {stage:<10} {fraction:6.1%}", end="", file=sys.stderr, flush=True)


def write_rows(fh, line_format: str, rows: np.ndarray, chunk: int = 1 << 16) -> None:
    """One line per row, a chunk of rows per %-format call: several times
    faster than np.savetxt, which formats row by row."""
    for start in range(0, len(rows), chunk):
        block = rows[start:start + chunk]
        fh.write((line_format * len(block)) % tuple(block.ravel().tolist()))


def write_obj(path: Path, scan, uvs: np.ndarray, face_page: np.ndarray, maps: list[dict]) -> None:
    """One vt per face corner keeps the writer trivial; importers weld them back.
    The maps' PNGs are encoded side by side (png_files, as the add-on does)."""
    stem = path.stem
    images = []
    with open(path.with_suffix(".mtl"), "w") as mtl:
        for page, roles in enumerate(maps):
            mtl.write(f"newmtl page{page}\nKd 1 1 1\n")
            for role, image in roles.items():
                name = f"{stem}_page{page}_{role}.png"
                images.append((path.parent / name, image))
                key = {"base_color": "map_Kd", "normal": "norm", "occlusion": "map_ao"}.get(role)
                if key:
                    mtl.write(f"{key} {name}\n")
    png_files.write_pngs(images)
    with open(path, "w") as obj:
        obj.write(f"mtllib {stem}.mtl\n")
        write_rows(obj, "v %.9g %.9g %.9g\n", scan.positions)
        write_rows(obj, "vt %.9g %.9g\n", uvs.reshape(-1, 2))
        corners = np.arange(3 * len(scan.triangles)).reshape(-1, 3) + 1
        for page in np.unique(face_page):
            faces = np.nonzero(face_page == page)[0]
            obj.write(f"usemtl page{page}\n" if page >= 0 else "usemtl untextured\n")
            rows = np.stack([scan.triangles[faces] + 1, corners[faces]], axis=2).reshape(len(faces), 6)
            write_rows(obj, "f %d/%d %d/%d %d/%d\n", rows)


def bake_maps(scan, result) -> list[dict]:
    """Bakes every map role the scan has, page by page of the new layout."""
    out_pages = [dict() for _ in result["page_sizes"]]
    roles = sorted({role for page in scan.maps for role in page})
    for role in roles:
        if any(role not in page for page in scan.maps):
            continue  # a role missing on some page cannot be baked consistently
        images = [scan_io.load_image(page[role]) for page in scan.maps]
        channels = min(im.shape[2] for im in images)
        images = [np.ascontiguousarray(im[:, :, :channels]) for im in images]
        baked = _native.bake(scan.uvs, scan.face_page, images, result["uvs"], result["face_page"],
                             result["page_sizes"], normal_map=role == "normal", progress=progress_line)
        for page, image in enumerate(baked):
            out_pages[page][role] = image
    return out_pages


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("input", type=Path)
    parser.add_argument("output", type=Path)
    parser.add_argument("--padding", type=int, default=4)
    parser.add_argument("--target-charts", type=int, default=0)
    parser.add_argument("--weighting", choices=["uv", "3d"], default="3d")
    args = parser.parse_args(argv)

    t0 = time.perf_counter()
    scan = scan_io.load(args.input)
    t_load = time.perf_counter() - t0
    options = {"padding": args.padding, "target_charts": args.target_charts, "weighting": args.weighting}
    result = _native.defragment(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                                options=options, progress=progress_line)
    t1 = time.perf_counter()
    new_maps = bake_maps(scan, result)
    t_bake = time.perf_counter() - t1
    if sys.stderr.isatty():
        print(file=sys.stderr)

    m = _native.measure(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                        result["uvs"], result["face_page"], result["page_sizes"])
    old_colour = [scan_io.load_image(page["base_color"]) for page in scan.maps]
    old_colour = [np.ascontiguousarray(im[:, :, :3]) for im in old_colour]
    new_colour = [np.ascontiguousarray(page["base_color"][:, :, :3]) for page in new_maps]
    fidelity = _native.compare_colors(scan.positions, scan.triangles, scan.uvs, scan.face_page, old_colour,
                                      result["uvs"], result["face_page"], new_colour)

    args.output.mkdir(parents=True, exist_ok=True)
    write_obj(args.output / f"{args.input.stem}_defrag.obj", scan, result["uvs"], result["face_page"], new_maps)

    r = result["report"]
    print(f"{args.input.name}: {len(scan.triangles)} faces")
    print(f"  charts        {r['charts_before']} -> {r['charts_after']} (aggregated {r['charts_aggregated']}, "
          f"split back: {r['splits_overlap']} overlap, {r['splits_density']} density, {r['splits_solver']} solver, "
          f"{r['splits_not_disk']} topology)")
    stops = ", ".join(f"{reason} {n}" for reason, n in r["aggregate_stops"].items() if n)
    print(f"  merges left   {stops or 'none'} (adjacent chart pairs, by what refused them)")
    print(f"  energy        median {r['energy_initial_median']:.2f} -> {r['energy_median']:.3f}, max {r['energy_max']:.2f} "
          f"over {r['charts_solved']} flattened charts (4 = isometric)")
    print(f"  seam length   {r['seam_before']:.1f} -> {r['seam_after']:.1f} (3D length / sqrt(area); "
          f"refinement moved {r['refine_faces_moved']} faces, removing {r['refine_seam_removed']:.2f})")
    print(f"  density rule  {r['density_reflattened']} charts flattened again to keep the surface's loss in budget; "
          f"{r['faces_detached']} faces made charts of their own (float32 would turn them over)")
    print(f"  texels        {r['texels_before']:,} -> {r['texels_after']:,} "
          f"(packing efficiency {r['packing_efficiency']:.1%}, scale {r['scale']:.3f})")
    print(f"  flipped       {m['old']['flipped_faces']} -> {m['new']['flipped_faces']}; "
          f"texels shared by two triangles {m['old']['overlap_texels']} -> {m['new']['overlap_texels']}")
    print(f"  density loss  {m['map']['density_loss_area_share']:.2%} of the area below half its texel density")
    print(f"  colour        PSNR {fidelity['psnr_db']:.1f} dB, {fidelity['share_off_32']:.2%} of points off by > 32/255")
    stages = ", ".join(f"{k} {v:.2f}" for k, v in r["seconds"].items())
    print(f"  seconds       load {t_load:.2f}, {stages}, bake {t_bake:.2f}")
    print(f"  written to    {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
