"""Packing and resampling on the real scans: efficiency, texels, page sizes, copied texels, PSNR.

    PYTHONPATH=build/addon .venv/bin/python bench/packing.py [--base-build DIR] [--no-xatlas]

For the three scans in ../shared/models, with Atlas Defrag's defaults:
  * packing efficiency (chart texels / page texels, padding not counted),
    texels before and after, scale, pack seconds (median of 3 runs); with
    --base-build, the same from another build of the module (before / after);
  * the same charts packed by xatlas (PyPI bindings, input UVs, padding 4,
    default and brute force), beside ours, all measured by one metric
    (_native.measure occupancy: page texels whose centre a triangle covers),
    and the bound the padding alone sets (chart texels / texels of the charts
    grown by the padding: what a packing with no gap at all would reach);
  * the padding as a ring each chart owns (default) or as the gap between two
    charts (padding_between_charts): efficiency, bound, clean mip levels;
  * cuts for packing (packing_cut_seam): efficiency, texels, seam, charts and
    seconds against the seam budget, with the padding as a ring of 4 (default)
    or 2, or as a gap of 4;
  * share of texels copied unresampled, PSNR on all / clean / border points;
  * page-side modes on the tetra scan; dense atlases (the Smithsonian scan with
    its maps downsampled to 512 x 512, the tetra and Meshroom charts packed
    tightly on 512 x 512 pages); 10,000 stacked charts.
Writes bench/PACKING.md. Not part of the test suite.
"""
from __future__ import annotations

import argparse
import datetime
import importlib.util
import io
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build"))
sys.path.insert(0, str(REPO / "tools"))

import scan_io  # noqa: E402

SCANS = {
    "meshroom": "meshroom_esp32cam/texturedMesh.obj",
    "smithsonian": "smithsonian_usnm1145291/usnm_1145291.glb",
    "tetra": "tetra_miniature/teTra-Mk5-miniature-model.obj",
}
PADDING = 4


def load_module(build: Path):
    """_native from a build folder (the add-on copy, or the build root)."""
    found = sorted((build / "addon" / "atlas_defrag").glob("_native*.so")) + sorted(build.glob("_native*.so"))
    if not found:
        raise SystemExit(f"no _native module in {build}")
    # scan_io reads OBJ files through the add-on's module: a second copy of
    # the same file cannot be loaded (pybind11 registers its types once).
    from atlas_defrag import _native
    if Path(_native.__file__).resolve() == found[0].resolve():
        return _native
    spec = importlib.util.spec_from_file_location("_native", found[0])
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def base_figures(build: Path, models: Path) -> dict:
    """Efficiency, texels and median pack seconds per scan from another build,
    in a child process: two builds of one pybind11 module cannot share one."""
    code = (
        "import json, sys; sys.path.insert(0, sys.argv[1]); import packing, scan_io; from pathlib import Path\n"
        "native = packing.load_module(Path(sys.argv[2])); out = {}\n"
        "for name, rel in packing.SCANS.items():\n"
        "    result, seconds = packing.defragment(native, scan_io.load(Path(sys.argv[3]) / rel))\n"
        "    r = result['report']; out[name] = [r['packing_efficiency'], r['texels_after'], seconds]\n"
        "print(json.dumps(out))\n")
    run = subprocess.run([sys.executable, "-c", code, str(HERE), str(build), str(models)], capture_output=True,
                         text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def args_of(scan):
    return scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes


def defragment(native, scan, options=None, runs=3):
    """The result of the last run and the median pack seconds."""
    seconds = []
    for _ in range(runs):
        result = native.defragment(*args_of(scan), options=options or {})
        seconds.append(result["report"]["seconds"]["pack"])
    return result, statistics.median(seconds)


def colour(native, scan, result):
    old = [np.ascontiguousarray(scan_io.load_image(p["base_color"])[:, :, :3]) for p in scan.maps]
    new, stats = native.bake(scan.uvs, scan.face_page, old, result["uvs"], result["face_page"], result["page_sizes"],
                             padding=int(result["page_padding"].max()), with_stats=True)
    fidelity = native.compare_colors(*args_of(scan)[:4], old, result["uvs"], result["face_page"],
                                     [np.ascontiguousarray(i[:, :, :3]) for i in new])
    return stats, fidelity


def chart_faces(result) -> list[np.ndarray]:
    return [np.nonzero(result["face_chart"] == c)[0] for c in range(len(result["charts"]["faces"]))]


def chart_texels(result, faces_of) -> list[np.ndarray]:
    """Each output chart's corners in texels of its page, as the packer placed it."""
    sizes = result["page_sizes"]
    return [result["uvs"][faces] * sizes[result["face_page"][faces[0]]][None, None, :] for faces in faces_of]


def occupancy(native, charts, new_uvs, new_sizes, new_face_page) -> float:
    """Share of page texels whose centre a chart triangle covers (the same metric for every packer)."""
    uv = np.concatenate([c.reshape(-1, 2) for c in charts])
    positions = np.zeros((len(uv), 3))
    positions[:, :2] = uv
    triangles = np.arange(len(uv)).reshape(-1, 3)
    side = float(max(1.0, uv.max()))
    m = native.measure(positions, triangles, (uv / side).reshape(-1, 3, 2), np.zeros(len(triangles), np.int32),
                       [[int(np.ceil(side))] * 2], new_uvs, new_face_page, new_sizes)
    return m["new"]["occupancy"]


def padding_bound(charts, padding: int) -> float:
    """Chart texels over texels of the charts grown by `padding` (square dilation)."""
    from PIL import Image, ImageDraw, ImageFilter

    raw = grown = 0
    for uv in charts:
        lo = np.floor(uv.reshape(-1, 2).min(0)) - padding - 2
        hi = np.ceil(uv.reshape(-1, 2).max(0)) + padding + 2
        im = Image.new("L", tuple(int(v) for v in hi - lo))
        draw = ImageDraw.Draw(im)
        for t in uv - lo:
            draw.polygon([tuple(p) for p in t], fill=255, outline=255)
        raw += int((np.asarray(im) > 0).sum())
        grown += int((np.asarray(im.filter(ImageFilter.MaxFilter(2 * padding + 1))) > 0).sum())
    return raw / grown


def hull_area(points: np.ndarray) -> float:
    """Area of the convex hull of (N, 2) points (Andrew's monotone chain)."""
    pts = np.unique(points, axis=0)
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]
    if len(pts) < 3:
        return 0.0

    def turns_left(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]) > 0

    def chain(seq):
        out = []
        for q in seq:
            while len(out) >= 2 and not turns_left(out[-2], out[-1], q):
                out.pop()
            out.append(q)
        return out[:-1]

    listed = pts.tolist()
    h = np.array(chain(listed) + chain(listed[::-1]))
    return 0.5 * abs(np.dot(h[:, 0], np.roll(h[:, 1], 1)) - np.dot(h[:, 1], np.roll(h[:, 0], 1)))


def shape_fill(charts, page_texels: int) -> list:
    """Cells of the chart-shape table: the charts' triangle area over the page,
    and per chart its area over its box as packed and over its convex hull,
    weighted by area; the share of the area in the three largest charts."""
    def twice_area(uv):
        e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
        return np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()

    area = np.array([0.5 * twice_area(uv) for uv in charts])
    box = np.array([np.prod(np.ptp(uv.reshape(-1, 2), axis=0)) for uv in charts])
    hull = np.array([hull_area(uv.reshape(-1, 2)) for uv in charts])
    w = area / area.sum()
    return [f"{area.sum() / page_texels:.1%}", f"{np.dot(w, area / np.maximum(box, 1e-12)):.2f}",
            f"{np.dot(w, area / np.maximum(hull, 1e-12)):.2f}", f"{np.sort(w)[::-1][:3].sum():.0%}"]


MIP_LEVELS = (1, 2, 3, 4)


def chart_ids(placed, size) -> np.ndarray:
    """Page of chart indices (-1: no chart) from the placed UVs, texel centres inside a triangle."""
    from PIL import Image, ImageDraw

    w, h = (int(v) for v in size)
    im = Image.new("I", (w, h), -1)
    draw = ImageDraw.Draw(im)
    for c, uv in enumerate(placed):
        for t in uv.reshape(-1, 3, 2) * [w, h]:
            draw.polygon([tuple(p) for p in t], fill=c)
    return np.asarray(im, np.int32)


def clean_at_mip(ids: np.ndarray, level: int) -> float:
    """Share of chart texels whose level-`level` mip texel and its 8 neighbours
    (all that a bilinear read there can touch; the page wraps) average no
    texel of another chart. Gap texels count as harmless."""
    b = 2 ** level
    h, w = -(-ids.shape[0] // b) * b, -(-ids.shape[1] // b) * b
    padded = np.full((h, w), -1, np.int32)
    padded[:ids.shape[0], :ids.shape[1]] = ids
    blocks = padded.reshape(h // b, b, w // b, b)
    high = blocks.max(axis=(1, 3))
    low = np.where(blocks < 0, np.iinfo(np.int32).max, blocks).min(axis=(1, 3))
    mixed = (high >= 0) & (low != high)
    clean = (high >= 0) & ~mixed
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            nh, nm = np.roll(high, (dy, dx), (0, 1)), np.roll(mixed, (dy, dx), (0, 1))
            clean &= (nh < 0) | (~nm & (nh == high))
    texels = (blocks >= 0).sum(axis=(1, 3))
    return float(texels[clean].sum() / texels.sum())


def padding_semantics(native, charts) -> list:
    """Efficiency, gap-free bound and clean mip texels with the padding as a ring
    each chart owns (the default) and as the gap between two charts."""
    cells = []
    for between in (False, True):
        r = native.pack_charts(charts, options={"padding": PADDING, "padding_between_charts": between})
        ids = chart_ids(r["uvs"], r["page_sizes"][0])
        bound = padding_bound(charts, PADDING // 2 if between else PADDING)
        cells += [f"{r['efficiency']:.1%}", f"{bound:.1%}"] + [f"{clean_at_mip(ids, k):.1%}" for k in MIP_LEVELS]
    return cells


CUT_BUDGETS = (0.0, 0.5, 1.0, 2.0, 3.0, 5.0)
PADDINGS = (("ring 4", {}), ("ring 2", {"padding": 2}), ("gap 4", {"padding_between_charts": True}))


def cut_rows(native, name, scan) -> list:
    """One row per padding and seam budget: what the cuts buy and cost."""
    rows = []
    for label, padding in PADDINGS:
        for budget in CUT_BUDGETS if not padding else (0.0, 1.0, 3.0):
            cut, pack = [], []
            for _ in range(3):
                r = native.defragment(*args_of(scan), options={**padding, "packing_cut_seam": budget})["report"]
                cut.append(r["seconds"]["cut"])
                pack.append(r["seconds"]["pack"])
            rows.append(f"| {name} | {label} | {budget:g} | {r['packing_efficiency']:.1%} | {r['texels_after']:,} | "
                        f"{r['seam_after']:.2f} | {r['charts_after']} | {r['packing_cuts']} | "
                        f"{statistics.median(cut):.3f} | {statistics.median(pack):.3f} |")
    return rows


def xatlas_pack(native, charts, brute: bool):
    import xatlas

    uv = np.concatenate([c.reshape(-1, 2) for c in charts])
    positions = np.zeros((len(uv), 3), np.float32)
    positions[:, :2] = uv
    atlas = xatlas.Atlas()
    atlas.add_mesh(positions, np.arange(len(uv), dtype=np.uint32).reshape(-1, 3),
                   uvs=(uv / uv.max()).astype(np.float32))
    options = xatlas.PackOptions()
    options.padding = PADDING
    options.texels_per_unit = 1.0  # positions are the texels: density kept
    options.bruteForce = brute
    t = time.perf_counter()
    atlas.generate(chart_options=xatlas.ChartOptions(), pack_options=options)
    seconds = time.perf_counter() - t
    _, indices, new_uv = atlas[0]
    sizes = [[atlas.width, atlas.height]]
    occ = occupancy(native, charts, new_uv[indices].astype(np.float64), sizes, np.zeros(len(indices), np.int32))
    return atlas.width * atlas.height, occ, atlas.utilization, seconds


def dense_scan(scan, side=512):
    """The scan with every map downsampled to side x side (Lanczos)."""
    from PIL import Image

    maps = []
    for page in scan.maps:
        roles = {}
        for role, source in page.items():
            pixels = scan_io.load_image(source)[::-1]
            pixels = pixels[:, :, 0] if pixels.shape[2] == 1 else pixels  # grey maps load with one channel
            im = Image.fromarray(pixels).resize((side, side), Image.LANCZOS)
            buf = io.BytesIO()
            im.save(buf, "PNG")
            roles[role] = buf.getvalue()
        maps.append(roles)
    dense = scan_io.Scan(scan.positions, scan.triangles, scan.uvs, scan.face_page,
                         np.array([[side, side]] * len(scan.page_sizes), np.int32))
    dense.maps = maps
    return dense


def tightly_packed_scan(native, scan, side=512):
    """The scan's own charts packed by pack_charts with 1 texel of padding
    onto one side x side page (scaled to fit), its base colour baked there: a
    dense atlas like a phone app's (Apple Object Capture's pages are
    about three quarters full)."""
    from PIL import Image

    g = native.chart_graph(*args_of(scan))
    chart = np.asarray(g["face_chart"])
    textured = scan.face_page >= 0
    sizes = np.asarray(scan.page_sizes)
    texels = scan.uvs * sizes[np.maximum(scan.face_page, 0)][:, None, :]
    members = [np.nonzero(chart == c)[0] for c in range(g["chart_count"])]
    packed = native.pack_charts([texels[f] for f in members],
                                options={"padding": 1, "padding_follows_page": False, "fixed_page_size": side})
    uvs, face_page = scan.uvs.copy(), np.where(textured, 0, -1).astype(np.int32)
    for f, placed in zip(members, packed["uvs"]):
        uvs[f] = placed
    size = np.array([[side, side]], np.int32)
    old = [np.ascontiguousarray(scan_io.load_image(p["base_color"])[:, :, :3]) for p in scan.maps]
    page = native.bake(scan.uvs, scan.face_page, old, uvs, face_page, size, padding=1)[0]
    buf = io.BytesIO()
    Image.fromarray(page[::-1]).save(buf, "PNG")
    dense = scan_io.Scan(scan.positions, scan.triangles, uvs, face_page, size)
    dense.maps = [{"base_color": buf.getvalue()}]
    return dense, packed["efficiency"]


def stacked_charts(count=10000, size=1024.0, seed=0):
    rng = np.random.default_rng(seed)
    charts = []
    for _ in range(count):
        a = np.sort(rng.uniform(0, 2 * np.pi, 12))
        r = rng.uniform(0.5, 1.0, 12)
        rim = np.stack([np.cos(a) * r, np.sin(a) * r], 1) * size / 2 + size / 2
        centre = np.broadcast_to([size / 2, size / 2], rim.shape)
        charts.append(np.stack([centre, rim, np.roll(rim, -1, 0)], 1))
    return charts


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--base-build", type=Path, help="another build folder, measured as 'before'")
    p.add_argument("--no-xatlas", action="store_true")
    p.add_argument("--models", type=Path, default=REPO.parent / "shared" / "models")
    p.add_argument("--out", type=Path, default=HERE / "PACKING.md")
    args = p.parse_args()
    native = load_module(BUILD)
    base = base_figures(args.base_build, args.models) if args.base_build else None
    try:
        import xatlas
        have_xatlas = not args.no_xatlas
        xatlas_version = xatlas.__version__
    except ImportError:
        have_xatlas, xatlas_version = False, None
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                            text=True).stdout.strip()
    lines = ["# Packing and resampling benchmark", "",
             f"`bench/packing.py`, {datetime.datetime.now():%Y-%m-%d %H:%M}, commit `{commit}`, "
             f"padding {PADDING}, defaults otherwise; 2 shared cores, so seconds are noisy. "
             "Efficiency: chart texels (conservative raster) / page texels. Occupancy: page texels whose "
             "centre a triangle covers, the one metric applied to every packer. Padding bound: chart texels / "
             "texels of the charts grown by the padding, the efficiency of a packing without any gap.", ""]

    lines += ["## Packing per scan", "",
              "| scan | charts | efficiency | padding bound | texels in | texels out | scale | pack s |"
              + (" before: efficiency | texels out | pack s |" if base else ""),
              "|---|---:|---:|---:|---:|---:|---:|---:|" + ("---:|---:|---:|" if base else "")]
    xatlas_rows, colour_rows, semantic_rows, shape_rows, cut_table, results = [], [], [], [], [], {}
    for name, rel in SCANS.items():
        print(f"{name} ...", file=sys.stderr)
        scan = scan_io.load(args.models / rel)
        result, seconds = defragment(native, scan)
        results[name] = (scan, result)
        r = result["report"]
        faces_of = chart_faces(result)
        charts = chart_texels(result, faces_of)
        row = (f"| {name} | {r['charts_after']} | {r['packing_efficiency']:.1%} | {padding_bound(charts, PADDING):.1%} | "
               f"{r['texels_before']:,} | {r['texels_after']:,} | {r['scale']:.3f}{' (shrunk)' if r['shrunk'] else ''} | "
               f"{seconds:.3f} |")
        if base:
            efficiency, texels, b_seconds = base[name]
            row += f" {efficiency:.1%} | {texels:,} | {b_seconds:.3f} |"
        lines.append(row)
        semantic_rows.append("| " + " | ".join([name] + padding_semantics(native, charts)) + " |")
        shape_rows.append("| " + " | ".join([name, f"{r['packing_efficiency']:.1%}"]
                                            + shape_fill(charts, r["texels_after"])) + " |")
        cut_table += cut_rows(native, name, scan)
        if have_xatlas:
            order = np.concatenate(faces_of)  # the faces in the order of `charts`
            ours = occupancy(native, charts, result["uvs"][order], result["page_sizes"], result["face_page"][order])
            cells = [f"{name}", f"{r['texels_after']:,}", f"{ours:.1%}", f"{seconds:.2f}"]
            for brute in (False, True):
                texels, occ, util, xs = xatlas_pack(native, charts, brute)
                cells += [f"{texels:,}", f"{occ:.1%}", f"{util:.1%}", f"{xs:.2f}"]
            xatlas_rows.append("| " + " | ".join(cells) + " |")
        stats, fidelity = colour(native, scan, result)
        colour_rows.append(f"| {name} | {stats['copied_share']:.1%} | {fidelity['psnr_db']:.1f} | {fidelity['psnr_clean_db']:.1f} | "
                           f"{fidelity['psnr_border_db']:.1f} | {fidelity['clean_share']:.0%} |")
    lines.append("")

    if have_xatlas:
        lines += [f"## The same charts packed by xatlas {xatlas_version} (PyPI bindings)", "",
                  "Our output charts, in texels, given to xatlas as input UVs (positions = the texels, "
                  "`texels_per_unit` 1, padding 4). *xatlas utilization* is xatlas' own figure, which counts its "
                  "bilinear-dilated chart raster and so reads higher than either metric here.", "",
                  "| scan | ours: texels | occupancy | s | xatlas: texels | occupancy | utilization | s | "
                  "xatlas brute force: texels | occupancy | utilization | s |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"] + xatlas_rows + [""]

    mips = " | ".join(f"clean mip {k}" for k in MIP_LEVELS)
    lines += ["## Padding: a ring each chart owns, or the gap between two charts", "",
              f"The same charts packed with padding {PADDING} as a ring each chart owns (the default: charts "
              f"{2 * PADDING} texels apart) and as the gap between two charts (`padding_between_charts`, as in "
              f"xatlas: {PADDING} texels apart). Bound: the gap-free packing (charts grown by {PADDING}, or by "
              f"{PADDING // 2} for the gap). Clean mip k: share of chart texels whose mip-k texel (a 2^k box) and its "
              "8 neighbours, all a bilinear read there can touch, average no texel of another chart (gap texels, "
              "filled by pull-push, count as harmless; the page wraps).", "",
              f"| scan | ring: efficiency | bound | {mips} | gap: efficiency | bound | {mips} |",
              "|---|" + "---:|" * (4 + 2 * len(MIP_LEVELS))] + semantic_rows + [""]

    lines += ["## Chart shapes", "",
              "How much of their box and of their convex hull the output charts fill (UV area of their triangles "
              "over the area of the box they are packed in, or of their convex hull; means weighted by chart area), "
              "beside the packer's efficiency and the triangles' share of the page. A packing fills a page no "
              "better than its charts fill their boxes unless charts nest in each other's hollows.", "",
              "| scan | efficiency | triangle area / page | box fill | hull fill | area in the 3 largest charts |",
              "|---|---:|---:|---:|---:|---:|"] + shape_rows + [""]

    lines += ["## Cuts for packing: seam budget and padding", "",
              "The whole job at each `packing_cut_seam` (the seam the cuts may add, in the unit of seam: 3D length / "
              "sqrt(area); default 0) with the padding as a ring of 4 texels each chart owns (default), a ring of 2, "
              "or a gap of 4 between charts (`padding_between_charts`). Seconds: median of 3 runs of the cut and "
              "pack stages.", "",
              "| scan | padding | seam budget | efficiency | texels out | seam | charts | cuts | cut s | pack s |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"] + cut_table + [""]

    lines += ["## Resampling per scan", "",
              "Copied: covered texels taken unresampled from the old texel they land on. PSNR on 400k points "
              "drawn by area; clean points read four old texels of their own old chart, border points the rest.", "",
              "| scan | copied | PSNR all | clean | border | clean points |", "|---|---:|---:|---:|---:|---:|"]
    lines += colour_rows + [""]

    print("page sides ...", file=sys.stderr)
    scan, _ = results["tetra"]
    lines += ["## Page-side modes (tetra)", "", "| page_sides | square | pages | texels | efficiency |", "|---|---|---|---:|---:|"]
    for sides in ("tight", "multiple_of_4", "power_of_two"):
        for square in (False, True):
            result = native.defragment(*args_of(scan), options={"page_sides": sides, "square_pages": square})
            r = result["report"]
            lines.append(f"| {sides} | {'yes' if square else 'no'} | {' + '.join(f'{w}x{h}' for w, h in result['page_sizes'])} | "
                         f"{r['texels_after']:,} | {r['packing_efficiency']:.1%} |")
    lines.append("")

    print("dense atlases ...", file=sys.stderr)
    dense_atlases = [("smithsonian, maps at 512", dense_scan(results["smithsonian"][0]))]
    tight = {name: tightly_packed_scan(native, results[name][0]) for name in ("tetra", "meshroom")}
    dense_atlases += [(f"{name}, charts packed on 512", dense) for name, (dense, _) in tight.items()]
    lines += ["## Dense atlases", "",
              "The Smithsonian scan with its maps downsampled to 512 x 512 (a page half full of charts a few "
              "texels wide), and the tetra and Meshroom scans with their own charts packed by `pack_charts` "
              "with 1 texel of padding onto a 512 x 512 page ("
              + " and ".join(f"{efficiency:.0%}" for _, efficiency in tight.values())
              + " of it covered) and their base colour baked there. Targets (issue 16): clean PSNR >= 40 dB, "
              "density loss 0, texels <= 1.1x the input. "
              "Defaults cut charts for packing where the pages would outgrow the input by more than a tenth "
              "(`fit_cut_seam`); *no cut to fit* turns that off; *density_loss_budget 0* splits and slits charts "
              "until no face keeps less than half its density.", "",
              "| atlas | options | texels in | texels out | ratio | padding | scale | charts | seam | density loss | "
              "copied | PSNR all | clean | border |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for atlas, dense in dense_atlases:
        for label, options in (("defaults", {}), ("no cut to fit", {"fit_cut_seam": 0}),
                               ("padding 4 on every page", {"padding_follows_page": False}),
                               ("texels_at_most_input", {"texels_at_most_input": True}),
                               ("density_loss_budget 0", {"density_loss_budget": 0})):
            result = native.defragment(*args_of(dense), options=options)
            r = result["report"]
            m = native.measure(*args_of(dense), result["uvs"], result["face_page"], result["page_sizes"])
            stats, fidelity = colour(native, dense, result)
            lines.append(f"| {atlas} | {label} | {r['texels_before']:,} | {r['texels_after']:,} | "
                         f"{r['texels_after'] / r['texels_before']:.2f}x | {result['page_padding'].max()} | "
                         f"{r['scale']:.3f}{' (shrunk)' if r['shrunk'] else ''} | {r['charts_before']} -> "
                         f"{r['charts_after']}{' (cut to fit)' if r['cut_to_fit'] else ''} | "
                         f"{r['seam_before']:.1f} -> {r['seam_after']:.1f} | "
                         f"{m['map']['density_loss_area_share']:.2%} | "
                         f"{stats['copied_share']:.1%} | {fidelity['psnr_db']:.1f} | {fidelity['psnr_clean_db']:.1f} | "
                         f"{fidelity['psnr_border_db']:.1f} |")
    lines.append("")

    print("stacked charts ...", file=sys.stderr)
    charts = stacked_charts()
    lines += ["## 10,000 charts stacked on one 1024 x 1024 UV area", "",
              "CPU: user seconds of this process, less sensitive than wall time to other processes on the machine "
              "(the rasterisation runs on both cores, the placement on one).", "",
              "| options | pages | scale | efficiency | wall s | CPU s |", "|---|---|---:|---:|---:|---:|"]
    for options in ({"texel_budget": 1024 * 1024}, {"max_pages": 1}, {"max_pages": 1, "max_page_size": 4096}):
        t, cpu = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF).ru_utime
        r = native.pack_charts(charts, options={"padding": PADDING, **options})
        seconds, cpu = time.perf_counter() - t, resource.getrusage(resource.RUSAGE_SELF).ru_utime - cpu
        pages = r["page_sizes"].tolist()
        lines.append(f"| {options} | {len(pages)} x {pages[0][0]}x{pages[0][1]} | {r['scale']:.4f} | {r['efficiency']:.1%} | "
                     f"{seconds:.2f} | {cpu:.2f} |")
    lines.append("")
    args.out.write_text("\n".join(lines))
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
