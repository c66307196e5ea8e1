"""Stress cases of issue 15, one row each in bench/STRESS.md. Not part of the test suite.

    nice .venv/bin/python bench/stress.py [--cases scan4m,texture16k,stacked,groups,copies]

The table holds the cases of the last run only.

  scan4m      a 4,009,008-face scan (bench/make_large_scan.py --grid 578 --charts 60000), 8192^2 texture
  texture16k  the 1,009,200-face scan with a 16384^2 texture (make_large_scan.py --page 16384)
  stacked     10,000 separate one-triangle charts, all on the same UV triangle of a 1024^2 source
  groups      the same in 20 face groups of 500
  copies      1,000,000 copies of one triangle

Each case runs in a child process (through run_benchmark.run_child: wall time and peak
memory by wait4). The scans go through the numpy path (tools/scan_io + atlas_defrag.job,
as tools/defrag_scan.py, without writing files); the others through _native.defragment.
Every case then checks its output with _native.measure: no flipped triangle, no texel
covered twice (each set of copies of a face counted once), every face on a page, copies
where their original is. The generated scans are cached in
bench/.cache/ (the first run generates them: minutes).
"""
from __future__ import annotations

import argparse
import datetime
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import run_benchmark as rb  # puts the build and tools/ on the path

CACHE = rb.HERE / ".cache" / "stress"
CASES = {
    "scan4m": "4M-face scan, numpy path",
    "texture16k": "1M-face scan, 16384^2 texture, numpy path",
    "stacked": "10,000 one-triangle charts stacked on one UV triangle",
    "groups": "the same 10,000, 20 face groups of 500",
    "copies": "1,000,000 copies of one triangle",
}
SCANS = {"scan4m": {"grid": 578, "charts": 60000}, "texture16k": {"page": 16384}}


def stacked_triangles(n: int, groups: int):
    """n separate random triangles whose UVs are all one triangle of a 1024^2 source."""
    rng = np.random.default_rng(1)
    positions = rng.random((3 * n, 3))
    triangles = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
    uvs = np.broadcast_to(rng.random((1, 3, 2)), (n, 3, 2)).copy()
    return positions, triangles, uvs, np.zeros(n, np.int32), np.array([[1024, 1024]], np.int32), \
        (np.arange(n) // (n // groups)).astype(np.int32)


def copies_of_a_triangle(n: int):
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    triangles = np.tile(np.array([[0, 1, 2]], np.int32), (n, 1))
    uvs = np.random.default_rng(1).random((n, 3, 2))
    return positions, triangles, uvs, np.zeros(n, np.int32), np.array([[1024, 1024]], np.int32), None


def run_scan(case: str):
    """(input arrays, result arrays, report, source texture side) through atlas_defrag.job."""
    import defrag_scan
    import make_large_scan
    import scan_io
    from atlas_defrag import _native, job

    scan = scan_io.load(make_large_scan.generate(rb.HERE / ".cache", **SCANS[case]))
    result = job.run(defrag_scan.job_input(scan), job.Options(padding=4), native=_native)
    before = (scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes)
    return before, (result.uvs, result.face_page, result.page_sizes), result.report


def run_synthetic(case: str):
    from atlas_defrag import _native

    if case == "copies":
        *before, group = copies_of_a_triangle(1_000_000)
    else:
        *before, group = stacked_triangles(10_000, 20 if case == "groups" else 1)
    r = _native.defragment(*before, face_group=group)
    return before, (r["uvs"], r["face_page"], r["page_sizes"]), r["report"]


def worker(case: str, out: Path) -> int:
    """Inside the child: the case, then its checks; the figures to `out` as JSON."""
    from atlas_defrag import _native

    t0 = time.perf_counter()
    before, after, report = (run_scan if case in SCANS else run_synthetic)(case)
    seconds = time.perf_counter() - t0
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # before the checks
    uvs, face_page, page_sizes = after
    # Copies of a face cover its texels again by design: the checks count each face once,
    # and the copies must sit where their original does.
    _, first, face_of = np.unique(np.sort(before[1], axis=1), axis=0, return_index=True, return_inverse=True)
    face_of = face_of.reshape(-1)
    same_corners = (before[1] == before[1][first][face_of]).all(axis=1)  # copies not rotated
    copies_follow = bool(np.array_equal(uvs[same_corners], uvs[first][face_of][same_corners]))
    positions, triangles, old_uvs, old_page, old_sizes = before
    m = _native.measure(positions, triangles[first], old_uvs[first], old_page[first], old_sizes,
                        uvs[first], face_page[first], page_sizes)
    textured = before[3] >= 0
    placed = bool((face_page[textured] >= 0).all() and np.isfinite(uvs[textured]).all()
                  and ((uvs[textured] >= 0) & (uvs[textured] <= 1)).all())
    out.write_text(json.dumps({
        "faces": int(len(before[1])), "source_pages": before[4].tolist(), "pages": page_sizes.tolist(),
        "charts": [int(report["charts_before"]), int(report["charts_after"])],
        "duplicate_faces": int(report.get("duplicate_faces", 0)), "scale": float(report["scale"]),
        "seconds": seconds, "stage_seconds": {k: float(v) for k, v in report["seconds"].items()},
        "peak_kb_defrag": peak_kb, "flipped": int(m["new"]["flipped_faces"]),
        "overlap_texels": int(m["new"]["overlap_texels"]), "all_placed": placed and copies_follow}))
    return 0


def texture(sides) -> str:
    return ", ".join(f"{w}x{h}" for w, h in sides) if len(sides) <= 2 else f"{len(sides)} pages"


def row(case: str, child: dict, f: dict | None) -> str:
    if f is None:
        return f"| {CASES[case]} | | | | | {child['wall']:.1f} | {child['peak_mb'] / 1024:.2f} | " \
               f"| FAILED: exit {child['rc']}, {rb.tail(child['log'], 2)} |"
    stages = ", ".join(f"{k} {v:.1f}" for k, v in f["stage_seconds"].items() if k != "total")
    ok = f["flipped"] == 0 and f["overlap_texels"] == 0 and f["all_placed"]
    checks = (f"{f['flipped']} flipped, {f['overlap_texels']} texels covered twice, "
              f"{'every face placed' if f['all_placed'] else 'FACES NOT PLACED OR COPIES ASTRAY'}: {'ok' if ok else 'FAILED'}")
    return (f"| {CASES[case]} | {f['faces']:,} | {texture(f['source_pages'])} -> {texture(f['pages'])} | "
            f"{f['charts'][0]:,} -> {f['charts'][1]:,} | {f['seconds']:.1f} ({stages}) | {child['wall']:.1f} | "
            f"{f['peak_kb_defrag'] / 2**20:.2f} / {child['peak_mb'] / 1024:.2f} | {f['scale']:.3f} | {checks} |")


def write_table(rows: list[str]) -> Path:
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=rb.REPO, capture_output=True,
                            text=True).stdout.strip()
    lines = ["# Stress cases (issue 15)", "",
             f"`bench/stress.py`, {datetime.date.today()}, built from commit {commit}, "
             f"{rb.os.cpu_count()} cores, run under `nice` beside other work. Seconds: the case itself "
             "(load, defragment and bake for the scans, `_native.defragment` for the others), with the "
             "native stages in brackets (for the scans `layout` is the whole `_native.defragment`, the "
             "stages before it, and `bake` the new texture); wall: the whole child, checks included. "
             "Peak GB: when the case ended / the whole child (wait4), checks included.", "",
             "| case | faces | texture (source -> new) | charts | seconds (stages) | wall s | peak GB | scale "
             "| checks |", "|---|---|---|---|---|---|---|---|---|"] + rows
    path = rb.HERE / "STRESS.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default=",".join(CASES))
    p.add_argument("--timeout", type=float, default=1800)
    p.add_argument("--worker", nargs=2, metavar=("CASE", "OUT_JSON"), help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.worker:
        return worker(a.worker[0], Path(a.worker[1]))
    CACHE.mkdir(parents=True, exist_ok=True)
    rows = []
    for case in a.cases.split(","):
        if case in SCANS:  # generated outside the measured child
            import make_large_scan
            make_large_scan.generate(rb.HERE / ".cache", **SCANS[case])
        out = CACHE / f"{case}.json"
        out.unlink(missing_ok=True)
        child = rb.run_child([sys.executable, Path(__file__).resolve(), "--worker", case, out],
                             CACHE / f"{case}.log", case, a.timeout)
        figures = json.loads(out.read_text()) if child["rc"] == 0 and out.exists() else None
        rows.append(row(case, child, figures))
    print(write_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
