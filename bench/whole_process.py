"""Whole-process times of the two entries, judged against issue 13's targets.

    .venv/bin/python bench/whole_process.py                       # this build, 5 runs each
    .venv/bin/python bench/whole_process.py --base /path/to/other/checkout --large

Each job is a fresh process, timed from its start to its exit (wall), with its
peak memory (wait4, through run_benchmark's spawner): `tools/defrag_scan.py`
on the Smithsonian and Meshroom scans, as each build runs by default and
with its quality metrics measured (--metrics; builds before it measured them
by default), the Blender
batch entry on the Smithsonian and Meshroom scans (Blender's start-up to the
written GLB; the issue sets no target for Meshroom's), run as the README
runs it, Blender started with PYTHONPYCACHEPREFIX naming the batch entry's
bytecode cache, and on the Smithsonian scan without that variable too,
and with --large both entries on the generated 1M-face scan (the batch entry
writing GLB, and OBJ as the command-line entry does). With --base (a
checkout with its own build/), the base's and this build's runs alternate,
one of each per round, so that both see the same machine; the table gives
both medians and their ratio. One warm-up run of each comes first (file
cache). Rewrites the section "## Whole process" of bench/RESULTS.md
(run_benchmark.py keeps it).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

from profile_stages import LARGE, SCANS, replace_section  # noqa: E402
from run_benchmark import _SPAWN, host_speed_seconds, with_bytecode_cache  # noqa: E402

SECTION = "## Whole process"
# Issue 13's targets: seconds, and for the large scan peak memory in GB.
TARGETS = {"CLI, smithsonian": 2.4, "CLI with metrics, smithsonian": 2.4, "CLI, meshroom": 1.3,
           "CLI with metrics, meshroom": 1.3, "batch, smithsonian": 4.0, "CLI, large": 20.0, "batch, large": 20.0,
           "batch to OBJ, large": 20.0}
LARGE_MEMORY_GB = 3.0


def metrics_flag(cli: list, checkout: Path) -> list:
    """What makes that checkout's command-line entry measure the metrics."""
    env = dict(os.environ, PYTHONPATH=str(checkout / "build" / "addon"))
    usage = subprocess.run(cli + ["--help"], env=env, capture_output=True, text=True).stdout
    return ["--metrics"] if "--metrics" in usage else []


def commands(checkout: Path, out: Path) -> dict:
    """label -> argv of each job, run from that checkout and its build."""
    cli = [sys.executable, str(checkout / "tools" / "defrag_scan.py")]
    metrics = metrics_flag(cli, checkout)
    plain_batch = ["blender", "--background", "--factory-startup", "--python-exit-code", "1",
                   "--python", str(checkout / "build" / "addon" / "atlas_defrag" / "batch.py"), "--"]
    batch = with_bytecode_cache(plain_batch)
    jobs = {"CLI, smithsonian": cli + [str(SCANS["smithsonian"]), str(out / "cli_s")],
            "CLI with metrics, smithsonian": cli + [str(SCANS["smithsonian"]), str(out / "cli_s")] + metrics,
            "CLI, meshroom": cli + [str(SCANS["meshroom"]), str(out / "cli_m")],
            "CLI with metrics, meshroom": cli + [str(SCANS["meshroom"]), str(out / "cli_m")] + metrics,
            "batch, smithsonian": batch + [str(SCANS["smithsonian"]), str(out / "batch_s.glb")],
            "batch without PYTHONPYCACHEPREFIX, smithsonian":
                plain_batch + [str(SCANS["smithsonian"]), str(out / "batch_s.glb")],
            "batch, meshroom": batch + [str(SCANS["meshroom"]), str(out / "batch_m.glb")]}
    if LARGE.exists():
        jobs["CLI, large"] = cli + [str(LARGE), str(out / "cli_l")]
        jobs["batch, large"] = batch + [str(LARGE), str(out / "batch_l.glb")]
        # OBJ in, OBJ out, as the command-line entry writes it
        jobs["batch to OBJ, large"] = batch + [str(LARGE), str(out / "batch_l.obj")]
    return jobs


def run(argv: list, checkout: Path) -> tuple:
    """(wall seconds, peak GB) of one job; raises if it fails."""
    env = dict(os.environ, PYTHONPATH=str(checkout / "build" / "addon"))
    with tempfile.NamedTemporaryFile(suffix=".json") as usage:
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", _SPAWN, usage.name] + argv, env=env, cwd=checkout,
                              capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if done.returncode != 0:
            raise RuntimeError(f"{argv} failed: {done.stdout[-2000:]} {done.stderr[-2000:]}")
        return wall, json.loads(Path(usage.name).read_text())["maxrss_kb"] / 2 ** 20


def measure(labels: list, builds: dict, runs: int) -> dict:
    """label -> build name -> [(wall, GB)], the builds alternating in every round."""
    results = {label: {name: [] for name in builds} for label in labels}
    for label in labels:
        for name, (checkout, jobs) in builds.items():  # warm-up
            run(jobs[label], checkout)
        for round_ in range(runs):
            for name, (checkout, jobs) in builds.items():
                results[label][name].append(run(jobs[label], checkout))
            print(f"[whole_process] {label}: round {round_ + 1}/{runs}", file=sys.stderr, flush=True)
    return results


def git_head(checkout: Path) -> str:
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=checkout, capture_output=True,
                          text=True).stdout.strip()


def section(results: dict, builds: dict, runs: int, speeds: tuple) -> list:
    """The section's lines; speeds: host_speed_seconds before and after the runs."""
    names = list(builds)
    heads = {name: git_head(checkout) for name, (checkout, _) in builds.items()}
    lines = [SECTION, "",
             f"`bench/whole_process.py`, {time.strftime('%Y-%m-%d %H:%M')}, load average "
             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the end. Fresh processes, wall seconds from "
             f"start to exit and peak memory, medians of {runs} runs"
             + (", the builds alternating run by run" if len(names) > 1 else "") + "; "
             + ", ".join(f"{name}: commit `{heads[name]}`" for name in names)
             + f". Host speed (`run_benchmark.host_speed_seconds`, lower is faster; the host drifts by up to 2x "
             f"within a day, so a target met here may be missed in a slow hour): {speeds[0]:.2f} s before, "
             f"{speeds[1]:.2f} s after. Targets: issue 13.", ""]
    header = "| job | target | " + " | ".join(f"{n}: s | {n}: GB" for n in names)
    lines += [header + (" | ratio |" if len(names) > 1 else " |") + " met? |",
              "|---|---:|" + "---:|---:|" * len(names) + ("---:|" if len(names) > 1 else "") + "---|"]
    for label, by_build in results.items():
        medians = {n: (statistics.median(w for w, _ in by_build[n]), max(g for _, g in by_build[n])) for n in names}
        wall, peak = medians[names[-1]]
        cells = " | ".join(f"{medians[n][0]:.2f} | {medians[n][1]:.2f}" for n in names)
        ratio = f" | {medians[names[0]][0] / wall:.2f}x" if len(names) > 1 else ""
        if label not in TARGETS:  # measured beside the targets, not set by the issue
            lines.append(f"| {label} | - | {cells}{ratio} | - |")
            continue
        met = wall <= TARGETS[label] and ("large" not in label or peak <= LARGE_MEMORY_GB)
        target = f"<= {TARGETS[label]:g} s" + (f", <= {LARGE_MEMORY_GB:g} GB" if "large" in label else "")
        lines.append(f"| {label} | {target} | {cells}{ratio} | {'yes' if met else 'no'} |")
    return lines + [""]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--base", type=Path, help="another checkout with its own build/, run alternately")
    p.add_argument("--large", action="store_true", help=f"also the generated scan ({LARGE})")
    p.add_argument("--results", type=Path, default=HERE / "RESULTS.md")
    args = p.parse_args(argv)
    if args.large and not LARGE.exists():
        p.error(f"--large needs {LARGE}: generate it first with bench/make_large_scan.py")
    with tempfile.TemporaryDirectory(prefix="whole_process_") as scratch:
        out = Path(scratch)
        builds = {}
        if args.base:
            builds["base"] = (args.base.resolve(), commands(args.base.resolve(), out / "base"))
        builds["this"] = (REPO, commands(REPO, out / "this"))
        labels = [label for label in builds["this"][1] if args.large or "large" not in label]
        before = host_speed_seconds()
        results = measure(labels, builds, args.runs)
        lines = section(results, builds, args.runs, (before, host_speed_seconds()))
    print("\n".join(lines))
    replace_section(args.results, lines, SECTION)
    return 0


if __name__ == "__main__":
    sys.exit(main())
