"""Builds the native module for this machine and packs the add-on zip of one
platform: dist/atlas_defrag-<version>-<platform>-cp<XY>.zip, its manifest
naming only that platform (Blender 4.2+ installs it only there; Blender 3.x
reads bl_info and ignores the manifest).

    python tools/platform_zip.py --platform linux-x64 [--build-dir DIR] [-- CMAKE_ARGS...]

The Python running this script is the one the module is built for (3.11 for
Blender 4.1 to 5.x, 3.10 for official Blender 3.x builds). A build folder that
is already configured is only rebuilt. .github/workflows/platform-zips.yml runs
this on each platform; the linux-x64 leg is tested in
python_tests/blender/test_bl_packaging.py.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "addon"))

from atlas_defrag import native_check  # noqa: E402  (no bpy)

PLATFORMS = ("windows-x64", "macos-arm64", "macos-x64", "linux-x64")


def build(build_dir: Path, cmake_args) -> Path:
    """Configures (once) and builds the add-on stage; returns its folder."""
    if not (build_dir / "CMakeCache.txt").is_file():
        subprocess.run(["cmake", "-S", str(REPO), "-B", str(build_dir), "-DCMAKE_BUILD_TYPE=Release",
                        "-DATLAS_BUILD_TESTS=OFF", f"-DPython_EXECUTABLE={sys.executable}"] + list(cmake_args),
                       check=True)
    subprocess.run(["cmake", "--build", str(build_dir), "--config", "Release", "--target", "addon_zip",
                    "--parallel"], check=True)
    return build_dir / "addon" / "atlas_defrag"


def check_module(stage: Path, platform: str) -> Path:
    """The one native module in the stage, built for platform and this Python."""
    modules = sorted(stage.glob("_native*"))
    if len(modules) != 1:
        raise SystemExit(f"expected one native module in {stage}, found {[m.name for m in modules]}")
    built = native_check.built_for(modules[0].name)
    python = f"Python {sys.version_info[0]}.{sys.version_info[1]}"
    system = platform.split("-")[0]
    # macOS module names carry no architecture (cpython-311-darwin.so): the system must match.
    if not (built.startswith(platform) or built.startswith(system + ",")) or not built.endswith(python):
        raise SystemExit(f"{modules[0].name} is built for {built}, not {platform}, {python}")
    return modules[0]


def pack(stage: Path, platform: str, out_dir: Path) -> Path:
    manifest = (stage / "blender_manifest.toml").read_text()
    version = re.search(r'^version = "([^"]+)"', manifest, re.M).group(1)
    manifest = re.sub(r"^platforms = \[.*\]$", f'platforms = ["{platform}"]', manifest, flags=re.M)
    out_dir.mkdir(parents=True, exist_ok=True)
    tag = f"cp{sys.version_info[0]}{sys.version_info[1]}"
    path = out_dir / f"atlas_defrag-{version}-{platform}-{tag}.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(stage.iterdir()):
            name = f"atlas_defrag/{f.name}"
            if f.name == "blender_manifest.toml":
                z.writestr(name, manifest)
            elif f.is_file() and f.suffix not in (".pyc",):
                z.write(f, name)
    return path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--platform", required=True, choices=PLATFORMS)
    p.add_argument("--build-dir", type=Path, default=None, help="default: build-<platform>-cp<XY>")
    p.add_argument("--out-dir", type=Path, default=REPO / "dist")
    p.add_argument("cmake_args", nargs="*", help="extra CMake arguments (after --)")
    args = p.parse_args(argv)
    tag = f"cp{sys.version_info[0]}{sys.version_info[1]}"
    stage = build(args.build_dir or REPO / f"build-{args.platform}-{tag}", args.cmake_args)
    check_module(stage, args.platform)
    print(pack(stage, args.platform, args.out_dir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
