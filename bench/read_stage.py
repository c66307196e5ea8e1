"""The add-on's read stage (bpy -> numpy) in Blender 3.4, 4.5 and 5.0.

    .venv/bin/python bench/read_stage.py            # the three real scans, 3 runs each
    .venv/bin/python bench/read_stage.py --large    # and the generated 1M-face scan

Each run is a fresh process of one Blender: Debian's Blender 3.4
(`blender --background`), the bpy 4.5 module (.venv) or the bpy 5.0 module
(.venv-bpy5). It imports the scan as the batch entry does, then times
`read_bpy.read` on its largest mesh, the whole stage: geometry, materials and
pixels, Blender's decoding of the images it loads included (asking an image's
size loads it, so the pixels cannot be timed apart fairly). Two routes: the
default one (PNGs Blender has not loaded decoded from their files, the others
through Blender with natively converted floats) and Blender's for every
image (`Image.pixels.foreach_get`). Medians over the runs, wall seconds.
Options: --runs N (default 3), --large, --results FILE (default
bench/RESULTS.md). Rewrites the section "## Reading in Blender" there
(run_benchmark.py keeps it).
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
sys.path.insert(0, str(HERE))

from profile_stages import LARGE, SCANS, replace_section  # noqa: E402

SECTION = "## Reading in Blender"
ADDON = REPO / "build" / "addon"
RUNTIMES = {
    "Blender 3.4": ["blender", "--background", "--factory-startup", "--python-exit-code", "1", "--python"],
    "bpy 4.5": [str(REPO / ".venv" / "bin" / "python")],
    "bpy 5.0": [str(REPO / ".venv-bpy5" / "bin" / "python")],
}
ROUTES = ("default", "blender")

# Runs inside the Blender of a runtime: argv ends with scan path, route.
CHILD = r'''
import json, sys, time
sys.path.insert(0, ADDON)
import bpy
from atlas_defrag import batch, read_bpy
scan, route = sys.argv[-2], sys.argv[-1]
bpy.ops.wm.read_factory_settings(use_empty=True)
objects = batch.import_model(scan)
obj = max((o for o in objects if o.type == "MESH"), key=lambda o: len(o.data.polygons))
if route == "blender":
    read_bpy._plain_png = lambda img: False
t = time.perf_counter()
read_bpy.read(obj)
print("READ_STAGE " + json.dumps({"read": time.perf_counter() - t}))
'''


def run_once(runtime: list, scan: Path, route: str, script: Path) -> dict:
    argv = runtime + [str(script)] + (["--"] if runtime[0] == "blender" else []) + [str(scan), route]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=900)
    for line in done.stdout.splitlines():
        if line.startswith("READ_STAGE "):
            return json.loads(line[len("READ_STAGE "):])
    raise RuntimeError(f"{argv} failed: {done.stdout[-1500:]} {done.stderr[-1500:]}")


def measure(scans: dict, runs: int, script: Path) -> dict:
    """(runtime, scan, route) -> median seconds, the routes alternating run by run."""
    samples = {}
    for runtime, argv in RUNTIMES.items():
        for name, scan in scans.items():
            for _ in range(runs):
                for route in ROUTES:
                    samples.setdefault((runtime, name, route), []).append(run_once(argv, scan, route, script))
            print(f"[read_stage] {runtime}, {name}", file=sys.stderr, flush=True)
    return {key: statistics.median(s["read"] for s in runs_) for key, runs_ in samples.items()}


def section(results: dict, scans: dict, runs: int) -> list:
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                          text=True).stdout.strip()
    lines = [SECTION, "",
             f"`bench/read_stage.py`, {time.strftime('%Y-%m-%d %H:%M')}, commit `{head}`, load average "
             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the end. `read_bpy.read` on the "
             f"imported scan (geometry, materials, pixels), wall seconds, medians of {runs} fresh processes "
             "per cell, the two routes alternating. Default: PNGs Blender has not loaded decoded from "
             "their files, other images through Blender; Blender's route: every image loaded by Blender "
             "and read through `Image.pixels.foreach_get`, floats turned into bytes natively.", "",
             "| Blender | scan | default | Blender's route | ratio |",
             "|---|---|---:|---:|---:|"]
    for runtime in RUNTIMES:
        for name in scans:
            d, b = results[(runtime, name, "default")], results[(runtime, name, "blender")]
            lines.append(f"| {runtime} | {name} | {d:.2f} | {b:.2f} | {b / max(d, 1e-9):.2f}x |")
    return lines + [""]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=3, help="fresh processes per cell (default 3)")
    p.add_argument("--large", action="store_true", help=f"also the generated scan ({LARGE})")
    p.add_argument("--results", type=Path, default=HERE / "RESULTS.md", help="the file whose section is rewritten")
    args = p.parse_args(argv)
    scans = {name: path for name, path in SCANS.items() if path.is_file()}
    if args.large:
        if not LARGE.exists():
            sys.exit(f"{LARGE} is missing: run bench/make_large_scan.py first")
        scans["large"] = LARGE
    script = HERE / ".cache" / "read_stage_child.py"
    script.parent.mkdir(parents=True, exist_ok=True)
    script.write_text(f"ADDON = {str(ADDON)!r}\n" + CHILD)
    lines = section(measure(scans, args.runs, script), scans, args.runs)
    print("\n".join(lines))
    replace_section(args.results, lines, SECTION)
    return 0


if __name__ == "__main__":
    sys.exit(main())
