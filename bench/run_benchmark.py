"""Atlas Defrag against the route Blender users know, on the real scans and a 1M-face scan.

    .venv/bin/python bench/run_benchmark.py [--models meshroom,smithsonian,tetra,large] [--skip-large]

For every model, in one run and one after another (never two jobs at once):
  * Atlas Defrag through the Blender batch entry (build/addon/atlas_defrag/batch.py):
    wall time including Blender's start, import and export; output in the input's format;
  * Atlas Defrag through the numpy path (tools/scan_io + atlas_defrag.job, as tools/defrag_scan.py);
  * Smart UV Project + Cycles EMIT bake in Blender (bench/blender_route.py).
Both Blender routes start with PYTHONPYCACHEPREFIX, as the README's batch command does.
Each job is a child process: wall time, peak resident memory (wait4), and the CPU
time other processes took meanwhile. Every route's new UVs and baked colour are
then measured by the same code (_native.measure, _native.compare_colors with
400k area-sampled points) against the input. Writes bench/RESULTS.md and, for
the Meshroom scan, pictures under bench/pictures/. Work files go to
bench/.cache/ (git-ignored); the large scan is generated there once.
Progress goes to stderr. Not part of the test suite.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys
import time
import traceback
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
# The add-on as built in build/addon/ is copied once per run (other engineers may rebuild
# it meanwhile): every route of one run uses the same module.
BUILT_ADDON = REPO / "build" / "addon"
SNAPSHOT = HERE / ".cache" / "addon_snapshot"
sys.path.insert(0, os.environ.get("ATLAS_BENCH_ADDON", str(BUILT_ADDON)))
sys.path.insert(0, str(REPO / "tools"))
sys.path.insert(0, str(HERE))

SHARED = REPO.parent / "shared" / "models"
MODELS = {
    "meshroom": SHARED / "meshroom_esp32cam" / "texturedMesh.obj",
    "smithsonian": SHARED / "smithsonian_usnm1145291" / "usnm_1145291.glb",
    "tetra": SHARED / "tetra_miniature" / "teTra-Mk5-miniature-model.obj",
    "large": None,  # bench/make_large_scan.py, generated on first use
}
REAL = ("meshroom", "smithsonian", "tetra")
KEPT_SECTIONS = ("## Where the time goes", "## Whole process", "## Reading in Blender")
# TextureDefrag's (charts, seam) on the real scans, quoted from issue 12 (see write_results).
TEXTURE_DEFRAG = {"meshroom": (124, 12.1), "smithsonian": (1719, 62.4), "tetra": (119, 23.9)}
# Issue 12's targets: at most (charts, seam) per real scan.
ISSUE_12_BOUNDS = {"meshroom": (90, 10.0), "smithsonian": (300, 40.0), "tetra": (80, 19.0)}
BATCH = SNAPSHOT / "atlas_defrag" / "batch.py"
ROUTES = ("batch", "numpy", "smartuv")
ROUTE_NAMES = {"input": "input", "batch": "Atlas Defrag, Blender batch",
               "numpy": "Atlas Defrag, numpy path", "smartuv": "Smart UV Project + Cycles bake"}


def with_bytecode_cache(cmd: list) -> list:
    """cmd started as the README starts Blender for the batch entry: with
    PYTHONPYCACHEPREFIX naming the batch entry's bytecode cache, so that
    Blender reads its start-up scripts compiled. Both Blender routes get it.
    (The add-on's folder is on sys.path from the top of this module.)"""
    from atlas_defrag.batch import bytecode_cache_dir
    return ["env", f"PYTHONPYCACHEPREFIX={bytecode_cache_dir()}"] + cmd


def log(msg: str) -> None:
    print(f"[bench {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


# ------------------------------------------------------------------ child processes
def _busy_seconds() -> float:
    """CPU seconds all processes have used since boot (/proc/stat)."""
    with open("/proc/stat") as f:
        parts = f.readline().split()[1:]
    v = [int(x) for x in parts]
    busy = v[0] + v[1] + v[2] + v[5] + v[6] + (v[7] if len(v) > 7 else 0)  # user nice system irq softirq steal
    return busy / os.sysconf("SC_CLK_TCK")


# The job runs as the grandchild of a small Python that reports its rusage: Linux keeps a
# process's peak RSS across fork and exec, so a job forked from this (large) process
# would report this process's memory as its own.
_SPAWN = """
import json, os, subprocess, sys
p = subprocess.Popen(sys.argv[2:])
_, status, ru = os.wait4(p.pid, 0)
with open(sys.argv[1], "w") as f:
    json.dump({"maxrss_kb": ru.ru_maxrss, "cpu": ru.ru_utime + ru.ru_stime}, f)
sys.exit(os.waitstatus_to_exitcode(status) & 255)
"""


def run_child(cmd, log_path: Path, label: str, timeout: float) -> dict:
    """Runs cmd, returns wall time, peak RSS of the job, and the others' CPU load meanwhile."""
    log(f"{label}: start")
    usage_path = Path(str(log_path) + ".rusage.json")
    usage_path.unlink(missing_ok=True)
    busy0, t0 = _busy_seconds(), time.perf_counter()
    with open(log_path, "w") as out:
        proc = subprocess.Popen([sys.executable, "-c", _SPAWN, str(usage_path)] + [str(c) for c in cmd],
                                stdout=out, stderr=subprocess.STDOUT, cwd=REPO, start_new_session=True)
    timed_out, next_note = False, 30.0
    while True:
        try:
            rc = proc.wait(timeout=0.05)
            break
        except subprocess.TimeoutExpired:
            pass
        elapsed = time.perf_counter() - t0
        if elapsed > timeout and not timed_out:
            timed_out = True
            os.killpg(proc.pid, 9)  # the group this call started: spawner and job
        if elapsed > next_note:
            log(f"{label}: running, {elapsed:.0f} s")
            next_note += 30.0
    wall = time.perf_counter() - t0
    try:
        usage = json.loads(usage_path.read_text())
    except (OSError, ValueError):
        usage = {"maxrss_kb": float("nan"), "cpu": 0.0}
    others = max(0.0, (_busy_seconds() - busy0 - usage["cpu"]) / wall) if wall > 0 else 0.0
    res = {"rc": rc, "wall": wall, "peak_mb": usage["maxrss_kb"] / 1024.0, "cpu": usage["cpu"],
           "others_load": others, "timed_out": timed_out, "log": str(log_path)}
    log(f"{label}: {'timed out' if timed_out else 'exit ' + str(rc)} after {wall:.1f} s, "
        f"peak {res['peak_mb']:.0f} MB, other processes {others:.2f} cores")
    return res


def tail(path: Path, lines: int = 6) -> str:
    try:
        text = Path(path).read_text(errors="replace").replace("\r", "\n").splitlines()
    except OSError:
        return ""
    keep = [ln for ln in text if ln.strip() and not ln.strip().endswith("%")]
    return " | ".join(keep[-lines:])


# ------------------------------------------------------------------ numpy-path worker
def worker_numpy(inp: Path, out_dir: Path) -> int:
    """Runs inside its own process so its peak memory is its own."""
    import scan_io
    import defrag_scan
    from atlas_defrag import _native, job

    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    scan = scan_io.load(inp)
    job_input = defrag_scan.job_input(scan)  # decodes the images
    t_load = time.perf_counter() - t0
    result = job.run(job_input, job.Options(padding=4), progress=defrag_scan.progress_line, native=_native)
    maps = defrag_scan.page_maps(result)
    t2 = time.perf_counter()
    defrag_scan.write_obj(out_dir / f"{inp.stem}_defrag.obj", scan, result.uvs, result.face_page, maps)
    t_write = time.perf_counter() - t2
    total = time.perf_counter() - t0
    np.savez(out_dir / "arrays.npz", uvs=result.uvs, face_page=result.face_page, page_sizes=result.page_sizes)
    seconds = {"load": t_load, **{k: v for k, v in result.report["seconds"].items() if k != "total"},
               "write": t_write, "total": total,
               "bench_io": time.perf_counter() - t0 - total}  # the arrays above: the benchmark's, not the job's
    colour = [str(out_dir / f"{inp.stem}_defrag_page{p}_base_color.png") for p in range(len(maps))]
    report = {k: v for k, v in result.report.items() if k != "seconds"}
    (out_dir / "worker.json").write_text(json.dumps({"seconds": seconds, "colour_pages": colour,
                                                     "report": report}, indent=2, default=float))
    print(file=sys.stderr)
    return 0


# ------------------------------------------------------------------ face matching
def _frames():
    """Ways a tool may have re-expressed the input's coordinates (Blender is Z-up, files Y-up)."""
    yield "as is", lambda p: p
    yield "blender z-up", lambda p: p[..., [0, 2, 1]] * np.array([1.0, 1.0, -1.0])
    yield "y-up to z-up", lambda p: p[..., [0, 2, 1]] * np.array([1.0, -1.0, 1.0])


_PERMS = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]])


def _match_in_frame(ref: np.ndarray, oth: np.ndarray, tol: float):
    f = len(ref)
    cr, co = ref.mean(axis=1), oth.mean(axis=1)
    h = 4 * tol
    qr, qo = np.floor(cr / h).astype(np.int64), np.floor(co / h).astype(np.int64)
    lo = np.minimum(qr.min(0), qo.min(0)) - 2
    span = np.maximum(qr.max(0), qo.max(0)) - lo + 3

    def key(q):
        q = q - lo
        return (q[:, 0] * span[1] + q[:, 1]) * span[2] + q[:, 2]

    ko = key(qo)
    order = np.argsort(ko, kind="stable")
    ks = ko[order]
    pr, po = [], []
    for d in np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij"), -1).reshape(-1, 3):
        kr = key(qr + d)
        left, right = np.searchsorted(ks, kr, "left"), np.searchsorted(ks, kr, "right")
        cnt = right - left
        total = int(cnt.sum())
        if not total:
            continue
        rr = np.repeat(np.arange(f), cnt)
        offs = np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        pr.append(rr)
        po.append(order[np.repeat(left, cnt) + offs])
    if not pr:
        return np.full(f, -1), np.zeros((f, 3), dtype=np.int64)
    pr, po = np.concatenate(pr), np.concatenate(po)
    errs = np.stack([np.abs(ref[pr] - oth[po][:, perm]).max(axis=(1, 2)) for perm in _PERMS], 1)
    best = errs.argmin(1)
    dist = errs[np.arange(len(pr)), best]
    ok = dist <= 3 * tol
    pr, po, best, dist = pr[ok], po[ok], best[ok], dist[ok]
    srt = np.argsort(dist, kind="stable")
    pr, po, best = pr[srt], po[srt], best[srt]
    match = np.full(f, -1, dtype=np.int64)
    perm = np.zeros(f, dtype=np.int64)
    used = np.zeros(len(oth), dtype=bool)
    for _ in range(8):  # mutual-best rounds settle duplicated faces
        free = (match[pr] < 0) & ~used[po]
        if not free.any():
            break
        a, b, c = pr[free], po[free], best[free]
        _, first_r = np.unique(a, return_index=True)
        first_r.sort()
        a, b, c = a[first_r], b[first_r], c[first_r]
        _, first_o = np.unique(b, return_index=True)
        a, b, c = a[first_o], b[first_o], c[first_o]
        match[a], perm[a], used[b] = b, c, True
    # A face the other mesh holds once for two identical input faces (Blender drops duplicates)
    # takes that one face's UVs.
    rest = match[pr] < 0
    if rest.any():
        a, b, c = pr[rest], po[rest], best[rest]
        _, first = np.unique(a, return_index=True)
        match[a[first]], perm[a[first]] = b[first], c[first]
    return match, _PERMS[perm]


def match_faces(ref: np.ndarray, oth: np.ndarray):
    """For each reference face (F,3,3 corner positions): the other face and its corner order.

    Returns (index into oth or -1, (F,3) corner permutation, frame name)."""
    diag = float(np.linalg.norm(ref.reshape(-1, 3).max(0) - ref.reshape(-1, 3).min(0)))
    tol = max(2e-6 * diag, 1e-9)
    best = None
    for name, frame in _frames():
        o = frame(oth.astype(np.float64))
        if o.shape == ref.shape and np.abs(o - ref).max() <= tol:
            return np.arange(len(ref)), np.tile(np.arange(3), (len(ref), 1)), name
        match, perm = _match_in_frame(ref, o, tol)
        found = int((match >= 0).sum())
        if best is None or found > best[0]:
            best = (found, match, perm, name)
        if found == len(ref):
            break
    return best[1], best[2], best[3]


def reorder(values: np.ndarray, match: np.ndarray, perm: np.ndarray) -> np.ndarray:
    """Per-corner values of the other mesh in the reference's face and corner order."""
    return values[match[:, None], perm]


# ------------------------------------------------------------------ metrics
def colour_pages(scan) -> list:
    import scan_io
    return [np.ascontiguousarray(scan_io.load_image(page["base_color"])[:, :, :3]) for page in scan.maps]


def measure(scan, old_colour, uvs, face_page, page_sizes, new_colour) -> dict:
    """The same figures for every route; `input_*` describe the scan itself."""
    from atlas_defrag import _native
    uvs = np.ascontiguousarray(uvs, dtype=np.float64)
    face_page = np.ascontiguousarray(face_page, dtype=np.int32)
    page_sizes = np.ascontiguousarray(page_sizes, dtype=np.int32).reshape(-1, 2)
    m = _native.measure(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                        uvs, face_page, page_sizes)
    c = _native.compare_colors(scan.positions, scan.triangles, scan.uvs, scan.face_page, old_colour,
                               uvs, face_page, new_colour, samples=400000)
    new = m["new"]
    return {"charts": new["charts"], "seam": new["seam_ratio"], "occupancy": new["occupancy"],
            "texels": int((page_sizes[:, 0].astype(np.int64) * page_sizes[:, 1]).sum()),
            "flipped": new["flipped_faces"], "overlap_texels": new["overlap_texels"],
            "psnr": c["psnr_db"], "off32": c["share_off_32"],
            "density_loss": m["map"]["density_loss_area_share"],
            "input": {"charts": m["old"]["charts"], "seam": m["old"]["seam_ratio"],
                      "occupancy": m["old"]["occupancy"],
                      "texels": int((scan.page_sizes[:, 0].astype(np.int64) * scan.page_sizes[:, 1]).sum()),
                      "flipped": m["old"]["flipped_faces"], "overlap_texels": m["old"]["overlap_texels"]}}


def unmatched_faces(scan, match: np.ndarray, what: str) -> np.ndarray:
    """Faces a route dropped: allowed only if they have no area (Blender drops faces that merging
    vertices collapses); they are left out of the new atlas (face_page -1), which no area-based
    figure notices. Anything else is an error."""
    missing = match < 0
    if missing.any():
        p = scan.positions[scan.triangles[missing]]
        area = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        if (area > 0).any():
            raise RuntimeError(f"{int(missing.sum())} of {len(match)} faces of {what} could not be matched "
                               f"to the input ({int((area > 0).sum())} of them with area)")
    return missing


def measure_output_model(scan, old_colour, path: Path) -> tuple[dict, dict]:
    """Loads a route's written model and measures it against the input, face by face."""
    import scan_io
    out = scan_io.load(path)
    match, perm, frame = match_faces(scan.positions[scan.triangles], out.positions[out.triangles])
    missing = unmatched_faces(scan, match, "the output")
    safe = np.where(missing, 0, match)
    uvs = np.where(missing[:, None, None], scan.uvs, reorder(out.uvs, safe, perm))
    face_page = np.where((scan.face_page >= 0) & ~missing, out.face_page[safe], -1)
    arrays = {"uvs": uvs, "face_page": face_page, "page_sizes": out.page_sizes, "dropped": int(missing.sum())}
    return measure(scan, old_colour, uvs, face_page, out.page_sizes, colour_pages(out)), arrays


def measure_smartuv(scan, old_colour, route_dir: Path, info: dict) -> tuple[dict, dict]:
    import scan_io
    z = np.load(route_dir / "route_arrays.npz")
    match, perm, frame = match_faces(scan.positions[scan.triangles], z["corners"])
    missing = unmatched_faces(scan, match, "Blender's mesh")
    safe = np.where(missing, 0, match)
    old_b = reorder(z["old_uv"].astype(np.float64), safe, perm)
    textured = (scan.face_page >= 0) & ~missing
    shared = ~missing & (np.bincount(safe, minlength=len(z["corners"]))[safe] > 1)  # duplicates merged
    check = textured & ~shared
    uv_err = float(np.abs(old_b - scan.uvs)[check].max()) if check.any() else 0.0
    if uv_err > 1e-4:
        raise RuntimeError(f"faces matched by position disagree on the old UVs (by {uv_err:.2g})")
    uvs = np.where(missing[:, None, None], scan.uvs, reorder(z["new_uv"].astype(np.float64), safe, perm))
    face_page = np.where(textured & z["textured"][safe], 0, -1).astype(np.int32)
    image = np.ascontiguousarray(scan_io.load_image(info["image"])[:, :, :3])
    sizes = np.array([[image.shape[1], image.shape[0]]], dtype=np.int32)
    arrays = {"uvs": uvs, "face_page": face_page, "page_sizes": sizes,
              "dropped": int(missing.sum()) + int(shared.sum()) // 2}
    return measure(scan, old_colour, uvs, face_page, sizes, [image]), arrays


# ------------------------------------------------------------------ pictures
def _chart_boundary_edges(scan, uvs, face_page):
    """Corner edges (face, corner) on a UV seam or the mesh border."""
    _, weld = np.unique(np.round(scan.positions, 9), axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    tri = weld[scan.triangles]
    f = len(tri)
    a, b = tri, np.roll(tri, -1, axis=1)
    ua, ub = uvs, np.roll(uvs, -1, axis=1)
    lo, hi = np.minimum(a, b).reshape(-1), np.maximum(a, b).reshape(-1)
    swap = (a > b).reshape(-1)
    p0 = np.where(swap[:, None], ub.reshape(-1, 2), ua.reshape(-1, 2))
    p1 = np.where(swap[:, None], ua.reshape(-1, 2), ub.reshape(-1, 2))
    page = np.repeat(face_page, 3)
    key = lo.astype(np.int64) * (weld.max() + 1) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    boundary = np.ones(3 * f, dtype=bool)
    same = np.nonzero(ks[1:] == ks[:-1])[0]
    i, j = order[same], order[same + 1]
    agree = (np.abs(p0[i] - p0[j]).max(1) < 1e-7) & (np.abs(p1[i] - p1[j]).max(1) < 1e-7) & (page[i] == page[j])
    boundary[i[agree]] = False
    boundary[j[agree]] = False
    return boundary.reshape(f, 3)


def _panel(image: np.ndarray, size: int, uvs=None, face_page=None, boundary=None):
    from PIL import Image, ImageDraw
    im = Image.fromarray(np.ascontiguousarray(image[::-1, :, :3])).convert("RGB")
    h, w = image.shape[:2]
    pw, ph = (size, max(1, round(size * h / w))) if w >= h else (max(1, round(size * w / h)), size)
    im = im.resize((pw, ph), Image.LANCZOS)
    if uvs is not None:
        overlay = Image.new("RGBA", (pw, ph), (0, 0, 0, 0))
        draw = ImageDraw.Draw(overlay)
        sel = face_page == 0
        xy = np.empty_like(uvs[sel])
        xy[..., 0] = uvs[sel][..., 0] * pw
        xy[..., 1] = (1.0 - uvs[sel][..., 1]) * ph
        bnd = boundary[sel]
        for tri in xy.tolist():
            draw.polygon([tuple(p) for p in tri], outline=(255, 255, 255, 70))
        for tri, edges in zip(xy.tolist(), bnd.tolist()):
            for k in range(3):
                if edges[k]:
                    draw.line([tuple(tri[k]), tuple(tri[(k + 1) % 3])], fill=(255, 220, 0, 255), width=1)
        im = Image.alpha_composite(im.convert("RGBA"), overlay).convert("RGB")
    box = Image.new("RGB", (size, size), (40, 40, 40))
    box.paste(im, (0, 0))
    return box


def _sheet(panels, captions, path: Path, title: str) -> None:
    from PIL import Image, ImageDraw, ImageFont
    size = panels[0].size[0]
    gap, head = 12, 60
    try:
        font = ImageFont.load_default(size=17)
    except TypeError:  # Pillow < 10.1
        font = ImageFont.load_default()
    sheet = Image.new("RGB", (len(panels) * size + (len(panels) + 1) * gap, size + head + gap), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    draw.text((gap, 6), title, fill=(255, 255, 255), font=font)
    for k, (p, cap) in enumerate(zip(panels, captions)):
        x = gap + k * (size + gap)
        draw.text((x, 32), cap, fill=(230, 230, 230), font=font)
        sheet.paste(p, (x, head))
    sheet.save(path, optimize=True)
    if path.stat().st_size > 1_000_000:  # photos in PNG: an adaptive palette keeps them under ~1 MB
        sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(path, optimize=True)


def make_pictures(scan, old_colour, routes: dict, out_dir: Path, size: int = 640) -> list:
    """Old atlas and the new ones side by side, plain and with the UV layout drawn over."""
    out_dir.mkdir(parents=True, exist_ok=True)
    entries = [("input", scan.uvs, scan.face_page, old_colour[0], scan.page_sizes[0])]
    for r in ("numpy", "smartuv"):
        if r in routes:
            a = routes[r]
            entries.append((r, a["uvs"], a["face_page"], a["colour"], a["page_sizes"][0]))
    captions, plain, wire = [], [], []
    for name, uvs, fp, img, sz in entries:
        boundary = _chart_boundary_edges(scan, uvs, fp)
        charts = routes.get(name, {}).get("charts")
        captions.append(f"{ROUTE_NAMES[name]}: {sz[0]}x{sz[1]}" + (f", {charts} charts" if charts else ""))
        plain.append(_panel(img, size))
        wire.append(_panel(img, size, uvs, fp, boundary))
    files = [out_dir / "meshroom_atlases.png", out_dir / "meshroom_uv_layouts.png"]
    _sheet(plain, captions, files[0], "Meshroom scan (meshroom_esp32cam): base colour atlas, each page scaled to "
           f"{size} px")
    _sheet(wire, captions, files[1], "Same atlases with the UV layout: triangle edges (white) and chart "
           "borders (yellow)")
    return files


# ------------------------------------------------------------------ one model
def run_model(name: str, path: Path, work: Path, args) -> dict:
    import scan_io
    ext = path.suffix.lower()
    mdir = work / name
    if mdir.exists():
        shutil.rmtree(mdir)
    mdir.mkdir(parents=True)
    res = {"model": name, "path": str(path), "routes": {}}
    blender = args.blender

    if "batch" in args.routes:
        out = mdir / "batch" / f"{path.stem}_defrag{'.obj' if ext == '.obj' else '.glb'}"
        out.parent.mkdir()
        rep = mdir / "batch" / "report.json"
        cmd = with_bytecode_cache([blender, "--background", "--factory-startup", "--python-exit-code", "1",
                                   "--python", BATCH, "--", path, out, "--report", rep])
        run = run_child(cmd, mdir / "batch.log", f"{name}: Atlas Defrag, Blender batch", args.timeout)
        r = {"run": run}
        if run["rc"] == 0 and rep.exists():
            report = json.loads(rep.read_text())
            obj = report["objects"][0]
            s = obj.get("seconds", {})
            stages = {"blender start": run["wall"] - report["seconds"]["total"], "import": report["seconds"]["import"]}
            for k in ("read", "charts", "aggregate", "flatten", "pack", "bake", "write"):
                if k in s:
                    stages[k] = s[k]
            stages["export"] = report["seconds"]["export"]
            r.update(stages=stages, output=str(out), report={k: v for k, v in obj.items()
                                                              if isinstance(v, (int, float, str))})
        else:
            r["error"] = "timed out" if run["timed_out"] else (tail(run["log"]) or f"exit {run['rc']}")
        res["routes"]["batch"] = r

    if "numpy" in args.routes:
        ndir = mdir / "numpy"
        cmd = [sys.executable, Path(__file__).resolve(), "--worker-numpy", path, ndir]
        run = run_child(cmd, mdir / "numpy.log", f"{name}: Atlas Defrag, numpy path", args.timeout)
        r = {"run": run}
        if run["rc"] == 0 and (ndir / "worker.json").exists():
            w = json.loads((ndir / "worker.json").read_text())
            stages = {"python start + imports": run["wall"] - w["seconds"]["total"] - w["seconds"]["bench_io"]}
            stages.update({k: v for k, v in w["seconds"].items() if k not in ("total", "bench_io")})
            stages["saving arrays for the benchmark"] = w["seconds"]["bench_io"]
            r.update(stages=stages, worker=w)
        else:
            r["error"] = "timed out" if run["timed_out"] else (tail(run["log"]) or f"exit {run['rc']}")
        res["routes"]["numpy"] = r

    if "smartuv" in args.routes:
        sdir = mdir / "smartuv"
        cmd = with_bytecode_cache([blender, "--background", "--factory-startup", "--python-exit-code", "1",
                                   "--python", HERE / "blender_route.py", "--", path, sdir, "--samples", args.samples])
        run = run_child(cmd, mdir / "smartuv.log", f"{name}: Smart UV Project + Cycles bake", args.timeout)
        r = {"run": run}
        if run["rc"] == 0 and (sdir / "route.json").exists():
            info = json.loads((sdir / "route.json").read_text())
            stages = {"blender start": run["wall"] - info["seconds"]["total"]}
            stages.update({k: v for k, v in info["seconds"].items() if k != "total"})
            r.update(stages=stages, info=info)
        else:
            r["error"] = "timed out" if run["timed_out"] else (tail(run["log"]) or f"exit {run['rc']}")
        res["routes"]["smartuv"] = r

    # Quality: the same code for every route.
    log(f"{name}: measuring")
    scan = scan_io.load(path)
    res["faces"] = int(len(scan.triangles))
    old_colour = colour_pages(scan)
    arrays = {}
    for route, r in res["routes"].items():
        if "error" in r:
            continue
        try:
            if route == "batch":
                r["metrics"], arrays[route] = measure_output_model(scan, old_colour, Path(r["output"]))
            elif route == "numpy":
                z = np.load(mdir / "numpy" / "arrays.npz")
                colour = [np.ascontiguousarray(scan_io.load_image(p)[:, :, :3]) for p in r["worker"]["colour_pages"]]
                r["metrics"] = measure(scan, old_colour, z["uvs"], z["face_page"], z["page_sizes"], colour)
                arrays[route] = {"uvs": z["uvs"], "face_page": z["face_page"], "page_sizes": z["page_sizes"],
                                 "colour": colour[0]}
            else:
                r["metrics"], arrays[route] = measure_smartuv(scan, old_colour, mdir / "smartuv", r["info"])
            if route != "numpy":
                arrays[route]["colour"] = None
            r["metrics"]["dropped_faces"] = int(arrays[route].get("dropped", 0))
            res["input"] = r["metrics"].pop("input")
        except Exception as exc:  # a measurement failure is recorded, never hidden
            r["measure_error"] = f"{type(exc).__name__}: {exc}"
            log(f"{name}: {route}: could not measure: {r['measure_error']}")
            traceback.print_exc()
    if "input" not in res:
        from atlas_defrag import _native
        g = _native.chart_graph(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes)
        res["input"] = {"charts": g["chart_count"], "texels": int(np.prod(scan.page_sizes, axis=1).sum())}

    if name == "meshroom" and not args.no_pictures:
        try:
            pics = {}
            for route in ("numpy", "smartuv"):
                if route in arrays:
                    a = dict(arrays[route])
                    if a["colour"] is None and route == "smartuv":
                        a["colour"] = scan_io.load_image(res["routes"]["smartuv"]["info"]["image"])
                    a["charts"] = res["routes"][route].get("metrics", {}).get("charts")
                    pics[route] = a
            pics["input"] = {"charts": res["input"]["charts"]}
            res["pictures"] = [str(p) for p in make_pictures(scan, old_colour, pics, args.pictures)]
        except Exception as exc:
            log(f"pictures failed: {type(exc).__name__}: {exc}")
            traceback.print_exc()
    (mdir / "result.json").write_text(json.dumps(res, indent=2, default=float))
    return res


# ------------------------------------------------------------------ RESULTS.md
def host_speed_seconds() -> float:
    """Seconds a fixed single-threaded workload takes (5M additions in the
    interpreter, median of 3): this host's speed drifts by up to 2x within a
    day, so runs compare only alongside this figure."""
    times = []
    for _ in range(3):
        start, total = time.perf_counter(), 0
        for i in range(5_000_000):
            total += i
        times.append(time.perf_counter() - start)
    return sorted(times)[1]


def machine() -> dict:
    cpu = platform.processor() or "?"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = 0
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = int(line.split()[1]) / 1024 / 1024
    except OSError:
        pass
    def git(*a):
        try:
            return subprocess.run(["git", "-C", str(REPO), *a], capture_output=True, text=True).stdout
        except OSError:
            return "?"
    dirty = [ln[3:] for ln in git("status", "--porcelain", "--untracked-files=no").splitlines() if len(ln) > 3]
    blender = "?"
    try:
        blender = subprocess.run(["blender", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    except (OSError, IndexError):
        pass
    import hashlib
    so = next(iter(sorted((SNAPSHOT / "atlas_defrag").glob("_native*.so"))), None)
    built = "?"
    if so is not None:
        built = (f"{so.name}, built {datetime.datetime.fromtimestamp(so.stat().st_mtime):%Y-%m-%d %H:%M}, "
                 f"sha256 {hashlib.sha256(so.read_bytes()).hexdigest()[:12]}")
    return {"native": built, "cpu": cpu, "cores": os.cpu_count(), "ram_gb": mem, "commit": git("rev-parse", "--short", "HEAD").strip(),
            "dirty": dirty, "blender": blender, "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
            "python": platform.python_version(), "speed": host_speed_seconds()}


def _fmt_int(v):
    return f"{v:,}" if isinstance(v, (int, np.integer)) else "–"


def _stages(st: dict) -> str:
    return ", ".join(f"{k} {v:.1f}" for k, v in st.items())


def write_results(results: list, mach: dict, args, path: Path, started: float) -> None:
    lines = []
    add = lines.append
    add("# Benchmark: Atlas Defrag against Smart UV Project + Cycles bake")
    add("")
    add("Run it from the repository root, after building (`cmake --build build --target addon_zip -j2`); "
        "the whole run took about 10 min on 2 cores (plus ~2 min, once, to generate the 1M-face scan):")
    add("")
    add("```sh")
    add(".venv/bin/python bench/run_benchmark.py                # all four models")
    add(".venv/bin/python bench/run_benchmark.py --skip-large   # only the three real scans")
    add(".venv/bin/python bench/run_benchmark.py --models meshroom")
    add("```")
    add("")
    add("It rewrites this file and `bench/pictures/`. Details: `bench/README.md`.")
    add("")
    add("## Run")
    add("")
    add(f"- Date: {mach['date']}; took {(time.time() - started) / 60:.0f} min.")
    add(f"- Machine: {mach['cores']} cores ({mach['cpu']}), {mach['ram_gb']:.0f} GB RAM; {mach['blender']} "
        f"(Debian), Python {mach['python']}. Host speed: a fixed single-threaded workload (5M additions in "
        f"Python, `host_speed_seconds`) took {mach['speed']:.2f} s; the host's speed drifts by up to 2x within a "
        "day, so compare seconds between runs only alongside this figure.")
    dirty = ""
    if mach["dirty"]:
        dirty = (f" The working tree had uncommitted changes (other engineers at work) in: "
                 f"{', '.join(mach['dirty'][:8])}{' …' if len(mach['dirty']) > 8 else ''}; see *Module* for what was measured.")
    add(f"- Commit: `{mach['commit']}`.{dirty}")
    add(f"- Module: a copy of `build/addon/atlas_defrag` taken at the start ({mach['native']}), used by every "
        "Atlas Defrag job and by the measurements.")
    add(f"- Settings: Atlas Defrag defaults (padding 4). Smart UV Project: angle limit 66°, island margin 0.001; "
        f"Cycles EMIT bake on the CPU, {args.samples} samples, denoising off, margin 16 px, into one image with "
        "as many texels as the input's pages together. Outputs are written in the input's format "
        "(OBJ in, OBJ out; GLB in, GLB out).")
    add("- Every job runs alone, one after another, in its own process. *Others* is the CPU (in cores) that "
        "processes outside the job used while it ran (builds and tests of other engineers): with 2 cores, "
        "anything above ~0.3 slowed the job down.")
    runs = [r["run"] for res in results for r in res["routes"].values() if "run" in r]
    busy = sum(r["others_load"] * r["wall"] for r in runs) / max(sum(r["wall"] for r in runs), 1e-9)
    if busy > 0.3:
        add(f"- **The machine was busy**: other processes used {busy:.1f} of the {mach['cores']} cores on average "
            "while the jobs ran, so every time below is longer (up to about twice) than on an idle machine; "
            "the quality figures do not depend on it.")
    add("")
    add("## Results")
    add("")
    add("Charts: connected groups of triangles whose UVs agree across edges. Seam: 3D length of the UV seams / "
        "sqrt(surface area). Occupancy: share of page texels covered by triangles. PSNR: base colour at 400k "
        "points drawn by surface area, bilinear, new atlas against the original. Density loss: share of the "
        "surface whose texel density fell below half of the original. Seconds: wall time per stage; "
        "*start* is the process's own start-up (Blender or Python) and whatever the stages do not cover.")
    add("")
    add("| model | faces | route | charts | seam | occupancy | texels | PSNR (dB) | density loss | seconds per stage | "
        "wall (s) | peak memory | others |")
    add("|---|---:|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    for res in results:
        inp = res.get("input", {})
        model = res["model"]
        faces = _fmt_int(res.get("faces"))
        add(f"| {model} | {faces} | input | {_fmt_int(inp.get('charts'))} | "
            f"{inp['seam']:.1f} | {inp['occupancy']:.1%} | {_fmt_int(inp.get('texels'))} | – | – | – | – | – | – |"
            if "seam" in inp else
            f"| {model} | {faces} | input | {_fmt_int(inp.get('charts'))} | – | – | {_fmt_int(inp.get('texels'))} "
            f"| – | – | – | – | – | – |")
        for route in ROUTES:
            r = res["routes"].get(route)
            if r is None:
                continue
            run = r["run"]
            m = r.get("metrics")
            if "error" in r:
                err = r["error"].replace("|", "/")[:300]
                add(f"| {model} | {faces} | {ROUTE_NAMES[route]} | **FAILED** | | | | | | {err} | "
                    f"{run['wall']:.1f} | {run['peak_mb'] / 1024:.2f} GB | {run['others_load']:.2f} |")
                continue
            if m:
                q = (f"{m['charts']:,} | {m['seam']:.1f} | {m['occupancy']:.1%} | {m['texels']:,} | "
                     f"{m['psnr']:.1f} | {m['density_loss']:.2%}")
            else:
                why = r.get("measure_error", "not measured").replace("|", "/")[:200]
                q = f"not measured: {why} | | | | |"
            label = ROUTE_NAMES[route]
            if m and m.get("dropped_faces"):
                label += f" ({m['dropped_faces']} duplicate or zero-area faces dropped by Blender's import)"
            add(f"| {model} | {faces} | {label} | {q} | {_stages(r['stages'])} | {run['wall']:.1f} | "
                f"{run['peak_mb'] / 1024:.2f} GB | {run['others_load']:.2f} |")
    add("")
    add("## Reference: TextureDefrag")
    add("")
    add("TextureDefrag (Maggiordomo, Cignoni, Tarini, EG 2021, built from its public source and run with its "
        "defaults), as quoted in issue 12, measured there with the same yardstick as here: charts are welded "
        "UV-connected faces; seam is the 3D length of UV seams / sqrt(area). Atlas Defrag: this run, numpy path.")
    add("")
    add("| model | charts in | Atlas Defrag | TextureDefrag | seam in | Atlas Defrag | TextureDefrag |")
    add("|---|---:|---:|---:|---:|---:|---:|")
    for res in results:
        ref = TEXTURE_DEFRAG.get(res["model"])
        m = res["routes"].get("numpy", {}).get("metrics")
        inp = res.get("input", {})
        if ref is None or not m or "seam" not in inp:
            continue
        add(f"| {res['model']} | {_fmt_int(inp.get('charts'))} | {m['charts']:,} | {ref[0]:,} | {inp['seam']:.1f} | "
            f"{m['seam']:.1f} | {ref[1]:.1f} |")
    add("")
    add("## Targets")
    add("")
    for line in target_lines(results):
        add(f"- {line}")
    add("")
    add("## Pictures (Meshroom scan)")
    add("")
    add("Old atlas, Atlas Defrag's and Smart UV Project's side by side, each page scaled to the same width "
        "(their real sizes are in the captions):")
    add("")
    add("![atlases](pictures/meshroom_atlases.png)")
    add("")
    add("The same with the UV layouts drawn over them: triangle edges white, chart borders yellow:")
    add("")
    add("![UV layouts](pictures/meshroom_uv_layouts.png)")
    add("")
    add("## Seams on the model")
    add("")
    add("The input's UV seams and Atlas Defrag's drawn on the three scans "
        "(`bench/seam_pictures.py`, run separately, seconds), and on the Meshroom scan as Atlas Defrag left "
        "them before issue 12's partial merges and seam refinement (commit 887a553, "
        "`ATLAS_BUILD_DIR=<its build> bench/seam_pictures.py --tag 887a553`):")
    add("")
    add("![Meshroom seams](pictures/meshroom_seams.png)")
    add("")
    add("![Meshroom seams before issue 12](pictures/meshroom_seams_887a553.png)")
    add("")
    add("![Smithsonian seams](pictures/smithsonian_seams.png)")
    add("")
    add("![tetra seams](pictures/tetra_seams.png)")
    add("")
    add("## Notes")
    add("")
    add("- Smart UV Project + one bake gives the base colour only; a scan with normal and occlusion maps "
        "(Smithsonian) needs one more bake per map on that route, which its times above do not include. "
        "Atlas Defrag's times include baking every map.")
    add("- Faces of each route are matched to the input's by their 3D corners, so both routes are measured on "
        "the input's own triangles (all scans here are triangles already).")
    add("- Numpy path: `tools/scan_io` reads the scan and the add-on's bpy-free job (`atlas_defrag.job.run`, "
        "as `tools/defrag_scan.py`) lays it out and bakes; decoding the images counts in *load*.")
    add("- The large scan is synthetic (`bench/make_large_scan.py`): the real-model targets are not judged on "
        "it, only its time and memory.")
    add("- The large scan is one smooth closed blob, the easy case for Smart UV Project (few, large islands); "
        "on the real scans it is the other way round.")
    # The sections of bench/profile_stages.py, whole_process.py and read_stage.py are theirs: kept.
    old = path.read_text() if path.exists() else ""
    for title in KEPT_SECTIONS:
        if "\n" + title in old:
            kept = old[old.index("\n" + title) + 1:]
            lines += [""] + [(kept[:kept.find("\n## ", 1)] if "\n## " in kept[1:] else kept).rstrip("\n")]
    path.write_text("\n".join(lines) + "\n")


def target_lines(results: list) -> list:
    by = {r["model"]: r for r in results}
    out = []

    def route_metric(res, route):
        r = res["routes"].get(route, {})
        return r.get("metrics")

    def judge(label, fn, fmt):
        parts, met, missing = [], True, []
        for name in REAL:
            res = by.get(name)
            if res is None:
                missing.append(name)
                continue
            for route in ("batch", "numpy"):
                m = route_metric(res, route)
                if not m:
                    if route in res["routes"]:
                        parts.append(f"{name} ({ROUTE_NAMES[route]}): not measured")
                        met = False
                    continue
                ok, text = fn(m, res.get("input", {}), name)
                met &= ok
                parts.append(f"{name} ({'batch' if route == 'batch' else 'numpy'}) {text}{'' if ok else ' ✗'}")
        if missing:
            parts.append("not run on " + ", ".join(missing))
        verdict = "**MET**" if met and not missing else ("**MISSED**" if not met else "**NOT JUDGED**")
        out.append(f"{verdict} — {label}: " + "; ".join(parts))

    judge("charts at most 15% of the input's on every real model",
          lambda m, i, _: (m["charts"] <= 0.15 * i["charts"],
                        f"{m['charts']}/{i['charts']} = {m['charts'] / i['charts']:.1%}"), None)
    judge("seam length at most half of the input's on every real model",
          lambda m, i, _: (m["seam"] <= 0.5 * i["seam"], f"{m['seam']:.1f}/{i['seam']:.1f} = {m['seam'] / i['seam']:.0%}"),
          None)
    judge("issue 12: charts at most 90 / 300 / 80 and seam at most 10.0 / 40 / 19 (Meshroom / Smithsonian / tetra)",
          lambda m, i, name: (m["charts"] <= ISSUE_12_BOUNDS[name][0] and m["seam"] <= ISSUE_12_BOUNDS[name][1],
                              f"{m['charts']} charts, seam {m['seam']:.1f}"), None)
    judge("colour PSNR at least 40 dB on every real model",
          lambda m, i, _: (m["psnr"] >= 40.0, f"{m['psnr']:.1f} dB"), None)
    judge("no flipped triangle in the output on every real model",
          lambda m, i, _: (m["flipped"] == 0, f"{m['flipped']} (input {i.get('flipped', '?')})"), None)
    judge("output texels at most the input's on every real model, and at most 2.6 M on the Meshroom scan",
          lambda m, i, name: (m["texels"] <= i["texels"] and (name != "meshroom" or m["texels"] <= 2_600_000),
                              f"{m['texels'] / 1e6:.2f} M of {i['texels'] / 1e6:.2f} M"), None)
    out.extend(stage_target_lines(by))

    res = by.get("smithsonian")
    r = res and res["routes"].get("batch")
    if not r:
        out.append("**NOT JUDGED** — whole job on the Smithsonian scan under 6 s: not run")
    elif "error" in r:
        out.append(f"**MISSED** — whole job on the Smithsonian scan under 6 s: the batch job failed ({r['error'][:120]})")
    else:
        w = r["run"]["wall"]
        inner = w - r["stages"]["blender start"]
        out.append(f"{'**MET**' if w < 6 else '**MISSED**'} — whole job on the Smithsonian scan under 6 s on 2 cores "
                   f"(Blender start, import and writing included): {w:.1f} s through the Blender batch entry "
                   f"({inner:.1f} s without Blender's own start-up; other processes used "
                   f"{r['run']['others_load']:.2f} cores meanwhile)")
    res = by.get("large")
    if not res:
        out.append("**NOT JUDGED** — 1M-face scan under 60 s with peak memory under 6 GB: not run (--skip-large)")
    else:
        for route in ("batch", "numpy"):
            r = res["routes"].get(route)
            if not r:
                continue
            if "error" in r:
                out.append(f"**MISSED** — 1M-face scan ({res.get('faces', 0):,} faces) under 60 s, peak under 6 GB, "
                           f"{ROUTE_NAMES[route]}: failed ({r['error'][:160]})")
                continue
            w, mem = r["run"]["wall"], r["run"]["peak_mb"] / 1024
            ok = w < 60 and mem < 6
            out.append(f"{'**MET**' if ok else '**MISSED**'} — 1M-face scan ({res.get('faces', 0):,} faces) under "
                       f"60 s with peak memory under 6 GB, {ROUTE_NAMES[route]}: {w:.1f} s"
                       f"{'' if w < 60 else ' ✗'}, {mem:.2f} GB{'' if mem < 6 else ' ✗'} "
                       f"(other processes {r['run']['others_load']:.2f} cores)")
    return out


def stage_target_lines(by: dict) -> list:
    """Targets on single stages, read from the numpy route's report (the same module as the batch)."""
    out = []
    workers = {name: by[name]["routes"].get("numpy", {}).get("worker") for name in REAL if name in by}
    w = workers.get("smithsonian")
    if w:
        flatten = w["seconds"]["flatten"]
        out.append(f"{'**MET**' if flatten < 3 else '**MISSED**'} — flattening stage (SLIM, SCAF and splits) on the "
                   f"Smithsonian scan under 3 s on 2 cores: {flatten:.2f} s (numpy path)")
    ratios = {n: w["report"] for n, w in workers.items() if w and w["report"].get("largest_chart_faces")}
    if ratios:
        ok = all(r["iteration_over_factorization"] <= 1.5 for r in ratios.values())
        out.append(f"{'**MET**' if ok else '**MISSED**'} — one SLIM iteration costs at most 1.5 numeric "
                   "factorizations of its chart's matrix (the largest chart each scan solved): " +
                   "; ".join(f"{n} {r['iteration_over_factorization']:.2f} ({r['largest_chart_faces']:,} faces)"
                             for n, r in ratios.items()))
    bake = by.get("meshroom", {}).get("bake_4096")
    if bake:
        out.append(f"{'**MET**' if bake['seconds'] < 1 else '**MISSED**'} — baking a 4096 x 4096 output on 2 cores "
                   f"under 1 s (resampling and pull-push fill): {bake['seconds']:.2f} s, the Meshroom base colour "
                   "laid out on a fixed 4096² page")
    return out


def worker_bake_4096(inp: Path, out_json: Path) -> int:
    """Times one bake into a 4096 x 4096 page, alone in its process."""
    import scan_io
    from atlas_defrag import _native

    scan = scan_io.load(inp)
    result = _native.defragment(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                                options={"fixed_page_size": 4096})
    images = [np.ascontiguousarray(scan_io.load_image(page["base_color"])[:, :, :3]) for page in scan.maps]
    best = float("inf")
    for _ in range(3):  # the fastest of three: the first also pays page faults on the input image
        t0 = time.perf_counter()
        _native.bake(scan.uvs, scan.face_page, images, result["uvs"], result["face_page"], result["page_sizes"])
        best = min(best, time.perf_counter() - t0)
    out_json.write_text(json.dumps({"seconds": best, "page_sizes": np.asarray(result["page_sizes"]).tolist()}))
    return 0


def run_bake_4096(path: Path, work: Path, args) -> dict | None:
    out = work / "bake_4096.json"
    run = run_child([sys.executable, Path(__file__).resolve(), "--worker-bake-4096", path, out],
                    work / "bake_4096.log", "meshroom: bake into 4096²", args.timeout)
    return json.loads(out.read_text()) if run["rc"] == 0 and out.exists() else None


# ------------------------------------------------------------------ main
def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "--worker-numpy":
        return worker_numpy(Path(argv[1]), Path(argv[2]))
    if argv and argv[0] == "--worker-bake-4096":
        return worker_bake_4096(Path(argv[1]), Path(argv[2]))
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--models", default="meshroom,smithsonian,tetra,large",
                   help="comma-separated subset of: " + ", ".join(MODELS))
    p.add_argument("--skip-large", action="store_true", help="leave out the generated 1M-face scan")
    p.add_argument("--routes", default=",".join(ROUTES), help="comma-separated subset of: " + ", ".join(ROUTES))
    p.add_argument("--samples", type=int, default=4, help="Cycles samples for the Smart UV route's bake")
    p.add_argument("--timeout", type=float, default=3600, help="seconds allowed per job")
    p.add_argument("--blender", default=os.environ.get("BLENDER", "blender"))
    p.add_argument("--work", type=Path, default=HERE / ".cache" / "runs")
    p.add_argument("--results", type=Path, default=HERE / "RESULTS.md")
    p.add_argument("--pictures", type=Path, default=HERE / "pictures")
    p.add_argument("--no-pictures", action="store_true")
    p.add_argument("--large-grid", type=int, default=290,
                   help="size of the generated scan (12 grid^2 triangles); smaller for a quick smoke run")
    p.add_argument("--large-charts", type=int, default=15000)
    p.add_argument("--large-page", type=int, default=8192)
    args = p.parse_args(argv)
    args.routes = [r for r in args.routes.split(",") if r]
    names = [m.strip() for m in args.models.split(",") if m.strip()]
    if args.skip_large and "large" in names:
        names.remove("large")
    for n in names:
        if n not in MODELS:
            p.error(f"unknown model {n!r}")
    if not (BUILT_ADDON / "atlas_defrag").is_dir():
        p.error("build the add-on first: cmake --build build --target addon_zip -j2")
    started = time.time()
    for attempt in range(12):  # a build may be writing the module right now: copy one that imports
        if SNAPSHOT.exists():
            shutil.rmtree(SNAPSHOT)
        shutil.copytree(BUILT_ADDON / "atlas_defrag", SNAPSHOT / "atlas_defrag",
                        ignore=shutil.ignore_patterns("__pycache__"))
        probe = subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {str(SNAPSHOT)!r}); "
                                "from atlas_defrag import _native"], capture_output=True, text=True)
        if probe.returncode == 0:
            break
        log(f"the built module does not import yet ({probe.stderr.strip()[-120:]}); retrying in 15 s")
        time.sleep(15)
    else:
        p.error("build/addon/atlas_defrag/_native does not import")
    os.environ["ATLAS_BENCH_ADDON"] = str(SNAPSHOT)
    sys.path.insert(0, str(SNAPSHOT))
    mach = machine()
    results = []
    for i, name in enumerate(names):
        path = MODELS[name]
        if name == "large":
            import make_large_scan
            log("large: generating the 1M-face scan if not cached (a few minutes, once)")
            path = make_large_scan.generate(HERE / ".cache", grid=args.large_grid, charts=args.large_charts,
                                            page=args.large_page)
        log(f"model {i + 1}/{len(names)}: {name} ({path})")
        results.append(run_model(name, Path(path), args.work, args))
        if name == "meshroom" and "numpy" in args.routes:
            results[-1]["bake_4096"] = run_bake_4096(Path(path), args.work, args)
        write_results(results, mach, args, args.results, started)  # partial results survive a crash
    log(f"wrote {args.results}")
    print(args.results.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
