"""Where the command-line entry's time goes, stage by stage, and how far each
stage is from its floor.

    .venv/bin/python bench/profile_stages.py                  # the three real scans, 3 runs each
    .venv/bin/python bench/profile_stages.py --large --runs 1 # and the generated 1M-face scan

Each run is a fresh process doing what tools/defrag_scan.py does (read, job,
metrics, write), timed per stage: wall seconds and the CPU seconds the process
used meanwhile (both threads; CPU far below 2 x wall means other processes had
the cores). Medians over the runs. Floors are measured in the same way:

  * start + imports: a Python that imports numpy and Pillow and nothing else;
  * read: the scan file's bytes read into memory;
  * decode: every PNG's pixel data inflated and its row filters undone
    natively (_native.png_pixels, what decode_png does less reading the
    chunks), Pillow decoding every other image once;
  * bake: allocating and writing every output texel once;
  * write: libdeflate level 1 over the output pixels (_native.zlib_compress),
    on 2 threads;
  * metrics: 0 (they are off without --metrics).

Charts, aggregate, flatten, refine, cut and pack have no floor measured here ("-"):
stopping every chart after one iteration is no floor for flatten, as the
charts it leaves unfinished are split and solved again.
Rewrites the section "## Where the time goes" of bench/RESULTS.md
(run_benchmark.py keeps it when it rewrites the rest).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
MODELS = Path(os.environ.get("ATLAS_MODELS_DIR", REPO.parent / "shared" / "models"))
SCANS = {
    "smithsonian": MODELS / "smithsonian_usnm1145291" / "usnm_1145291.glb",
    "meshroom": MODELS / "meshroom_esp32cam" / "texturedMesh.obj",
    "tetra": MODELS / "tetra_miniature" / "teTra-Mk5-miniature-model.obj",
}
LARGE = HERE / ".cache" / "large_scan" / "large_scan.obj"
SECTION = "## Where the time goes"

# Runs inside the child process: argv = scan, output folder.
CHILD = r'''
import json, os, sys, time
marks, last = [], [float(os.environ["PROFILE_T0"]), 0.0]
def mark(stage):
    now, cpu = time.time(), time.process_time()
    marks.append((stage, now - last[0], cpu - last[1] if marks else cpu))
    last[:] = [now, cpu]
import defrag_scan, scan_io
from atlas_defrag import _native, job
from pathlib import Path
mark("start + imports")
scan = scan_io.load(sys.argv[1]); mark("read")
inp = defrag_scan.job_input(scan); mark("decode")
res = job.run(inp, job.Options(), native=_native)
native = dict(res.report["seconds"])
mark("job")
defrag_scan.quality(scan, inp, res)  # the CLI runs it beside the writing; here apart, to time each
mark("metrics")
out = Path(sys.argv[2]); out.mkdir(parents=True, exist_ok=True)
defrag_scan.write_obj(out / "scan_defrag.obj", scan, res.uvs, res.face_page, defrag_scan.page_maps(res))
mark("write")
print(json.dumps({"marks": marks, "native": native, "faces": int(len(scan.triangles)),
                  "pixels": [int(im.pixels.size) for im in res.images]}))
'''

FLOOR_IMPORTS = "import time; t = time.time(); import numpy, PIL.Image; print(time.time() - {t0})"


def child_env() -> dict:
    paths = [str(REPO / "build" / "addon"), str(REPO / "tools")]
    return dict(os.environ, PYTHONPATH=os.pathsep.join(paths + [os.environ.get("PYTHONPATH", "")]))


def run_child(scan: Path, out: Path) -> dict:
    env = dict(child_env(), PROFILE_T0=repr(time.time()))
    done = subprocess.run([sys.executable, "-c", CHILD, str(scan), str(out)], env=env,
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def stage_rows(run: dict) -> dict:
    """stage -> (wall, cpu); the job's wall split into its native stages."""
    rows = {}
    for stage, wall, cpu in run["marks"]:
        if stage != "job":
            rows[stage] = (wall, cpu)
            continue
        seconds = run["native"]
        # Every stage the report times, in its order ("layout" sums the ones before it).
        for name, wall_s in seconds.items():
            if name not in ("layout", "total"):
                rows[name] = (wall_s, None)
        rows["job (other)"] = (wall - seconds.get("total", wall), None)
        rows["job total"] = (wall, cpu)
    return rows


def median_rows(runs: list) -> dict:
    rows = [stage_rows(r) for r in runs]
    out = {}
    for stage in rows[0]:
        walls = [r[stage][0] for r in rows]
        cpus = [r[stage][1] for r in rows if r[stage][1] is not None]
        out[stage] = (statistics.median(walls), statistics.median(cpus) if cpus else None)
    return out


def measured_floors(scan: Path, runs: list) -> dict:
    """stage -> floor seconds, as the module's docstring says."""
    import numpy as np
    from concurrent.futures import ThreadPoolExecutor

    sys.path[:0] = [str(REPO / "build" / "addon"), str(REPO / "tools")]
    import scan_io
    from atlas_defrag import _native, png_files

    env = child_env()
    t0 = time.time()
    imports = float(subprocess.run([sys.executable, "-c", FLOOR_IMPORTS.format(t0=repr(t0))], env=env,
                                   capture_output=True, text=True, check=True).stdout)
    t = time.perf_counter()
    sources = [scan] + sorted(p for p in scan.parent.iterdir() if p.suffix.lower() in (".mtl", ".png", ".jpg"))
    for p in sources:
        p.read_bytes()
    read = time.perf_counter() - t
    loaded = scan_io.load(scan)
    t = time.perf_counter()
    for roles in loaded.maps:
        for source in roles.values():
            data = source if isinstance(source, bytes) else Path(source).read_bytes()
            size = png_files.plain_png_size(data[:png_files.HEADER_BYTES])
            if size:
                _native.png_pixels(png_files._image_data(data), *size)
                continue
            from PIL import Image
            Image.MAX_IMAGE_PIXELS = None
            with Image.open(__import__("io").BytesIO(data)) as im:
                im.load()
    decode = time.perf_counter() - t
    pixels = runs[0]["pixels"]
    t = time.perf_counter()
    pages = [np.empty(n, dtype=np.uint8) for n in pixels]
    for page in pages:
        page.fill(1)
    bake = time.perf_counter() - t
    t = time.perf_counter()
    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(lambda a: _native.zlib_compress(a, 1), pages))
    write = time.perf_counter() - t
    return {"start + imports": imports, "read": read, "decode": decode, "bake": bake,
            "write": write, "metrics": 0.0}


def section(results: dict, runs: int) -> list:
    lines = [SECTION, "",
             f"`bench/profile_stages.py`, {time.strftime('%Y-%m-%d %H:%M')}, commit "
             f"`{subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=REPO, capture_output=True, text=True).stdout.strip()}`, "
             f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the end. Medians of {runs} runs "
             "of the command-line entry's stages in a fresh process each (read, job, metrics, write), wall "
             "seconds; CPU is the process's CPU seconds meanwhile (2 cores: CPU well below 2 x wall means other "
             "processes had the cores). Floors as the script's docstring says; x = stage / floor.", ""]
    for model, (rows, floors, faces) in results.items():
        total = sum(w for s, (w, _) in rows.items() if s != "job total")
        lines += [f"**{model}** ({faces:,} faces): {total:.2f} s in all", "",
                  "| stage | wall (s) | CPU (s) | floor (s) | x floor |", "|---|---:|---:|---:|---:|"]
        for stage, (wall, cpu) in rows.items():
            floor = floors.get(stage)
            ratio = f"{wall / floor:.1f}" if floor else "-"
            lines.append(f"| {stage} | {wall:.2f} | {'-' if cpu is None else f'{cpu:.2f}'} | "
                         f"{'-' if floor is None else f'{floor:.2f}'} | {ratio} |")
        lines.append("")
    return lines


def replace_section(path: Path, lines: list, title: str = SECTION) -> None:
    """The section called title in place of the old one (or at the end), the rest kept."""
    text = path.read_text() if path.exists() else ""
    head, found, rest = text.partition(title)
    after = rest.find("\n## ")
    tail = rest[after + 1:] if found and after >= 0 else ""
    path.write_text(head.rstrip("\n") + "\n\n" + "\n".join(lines).rstrip("\n") + "\n" + ("\n" + tail if tail else ""))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--models", default="smithsonian,meshroom,tetra")
    p.add_argument("--large", action="store_true", help=f"also the generated scan ({LARGE})")
    p.add_argument("--results", type=Path, default=HERE / "RESULTS.md")
    args = p.parse_args(argv)
    scans = {m: SCANS[m] for m in args.models.split(",") if m}
    if args.large:
        if not LARGE.exists():
            sys.exit(f"{LARGE} is missing: run bench/make_large_scan.py first")
        scans["large"] = LARGE
    out = HERE / ".cache" / "profile"
    results = {}
    for model, scan in scans.items():
        print(f"[profile] {model}", file=sys.stderr, flush=True)
        run_child(scan, out / model)  # warm-up: file cache
        runs = [run_child(scan, out / model) for _ in range(args.runs)]
        floors = measured_floors(scan, runs)
        results[model] = (median_rows(runs), floors, runs[0]["faces"])
    lines = section(results, args.runs)
    print("\n".join(lines))
    replace_section(args.results, lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
