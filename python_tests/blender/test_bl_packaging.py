# SPDX-License-Identifier: MIT
"""The add-on zip: its layout, the manifest, and installing it in Blender 3.4
(legacy add-on) and in bpy 4.5 (extension), then using it."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from blenv import ADDON_ZIP, HERE, REPO, require_native, run_blender


@pytest.fixture(scope="module")
def addon_zip():
    if not ADDON_ZIP.is_file():
        pytest.fail(f"{ADDON_ZIP} is missing: build it first (cmake --build build)")
    return ADDON_ZIP


def test_zip_layout(addon_zip):
    names = zipfile.ZipFile(addon_zip).namelist()
    files = {n for n in names if not n.endswith("/")}
    assert all(n.startswith("atlas_defrag/") for n in names), names
    for need in ("__init__.py", "blender_manifest.toml", "LICENSE", "LICENSE-libdeflate", "batch.py", "job.py",
                 "operators.py", "read_bpy.py", "write_bpy.py", "api.py", "compat.py"):
        assert f"atlas_defrag/{need}" in files, need
    assert any(n.startswith("atlas_defrag/_native") and n.endswith(".so") for n in files), files
    # Every .py of the source folder is shipped (flat, no subpackages).
    src = {p.name for p in (REPO / "addon" / "atlas_defrag").glob("*.py")}
    assert src <= {n.split("/", 1)[1] for n in files}, src


def test_manifest_and_bl_info():
    import tomllib
    man = tomllib.loads((REPO / "blender_manifest.toml").read_text())
    assert man["schema_version"] == "1.0.0"
    assert man["id"] == "atlas_defrag" and man["version"] == "0.1.0"
    assert man["blender_version_min"] == "4.2.0"
    assert man["platforms"] == ["linux-x64"] and man["license"] == ["SPDX:MIT"]
    assert man["type"] == "add-on"
    tree = ast.parse((REPO / "addon" / "atlas_defrag" / "__init__.py").read_text())
    bl_info = next(ast.literal_eval(n.value) for n in tree.body
                   if isinstance(n, ast.Assign) and getattr(n.targets[0], "id", "") == "bl_info")
    assert bl_info["version"] == (0, 1, 0) and bl_info["blender"] <= (3, 4, 0)
    assert ".".join(map(str, bl_info["version"])) == man["version"]


def test_no_absolute_package_imports():
    """Relative imports only: as an extension the package is bl_ext.<repo>.atlas_defrag."""
    for path in (REPO / "addon" / "atlas_defrag").glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                assert not node.module.startswith("atlas_defrag"), (path.name, node.module)
            if isinstance(node, ast.Import):
                assert not any(a.name.startswith("atlas_defrag") for a in node.names), path.name


def test_manifest_validates_with_blender_tool(addon_zip):
    import bpy
    tool = Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    if not tool.is_file():
        pytest.fail(f"extension tool not found at {tool}")
    proc = subprocess.run([sys.executable, str(tool), "validate", str(addon_zip)], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def _check(res, user_dir):
    if "skipped" in res:  # the scenario run with the installed add-on needs a missing scan
        pytest.skip(res["skipped"])
    assert res.get("ok"), res.get("error")
    assert res["operator"]
    assert res["package"].startswith(str(user_dir)), res["package"]
    assert res["native"].startswith(str(user_dir)), res["native"]


def test_install_legacy_blender34(addon_zip, tmp_path):
    require_native()
    user = tmp_path / "scripts"
    out = tmp_path / "result.json"
    proc = run_blender(["--python", str(HERE / "bl_install.py"), "--", "--zip", str(addon_zip), "--out", str(out)],
                       env={"BLENDER_USER_SCRIPTS": str(user), "BLENDER_USER_CONFIG": str(tmp_path / "config")})
    assert out.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    res = json.loads(out.read_text())
    assert res["blender"].startswith("3."), res
    _check(res, user)
    assert res["enabled"] == ["atlas_defrag"]


def test_install_extension_bpy45(addon_zip, tmp_path):
    require_native()
    user = tmp_path / "resources"
    out = tmp_path / "result.json"
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(user))
    env.pop("PYTHONPATH", None)  # the installed copy, not the build folder
    proc = subprocess.run([sys.executable, str(HERE / "bl_install.py"), "--zip", str(addon_zip), "--out", str(out)],
                          capture_output=True, text=True, timeout=900, env=env)
    assert out.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    res = json.loads(out.read_text())
    import bpy
    assert res["blender"] == bpy.app.version_string, res  # the bpy of this venv: 4.5, or 5.0 (test_bl_bpy50.py)
    _check(res, user)
    assert res["enabled"] == ["bl_ext.user_default.atlas_defrag"]


def test_platform_zip_linux_leg(tmp_path):
    """The linux-x64 leg of .github/workflows/platform-zips.yml, with its own
    command (tools/platform_zip.py) on the build folder: a zip whose manifest
    names linux-x64 only and that Blender's extension tool accepts; asking it
    for another platform is refused, naming what the module is built for."""
    import bpy
    from blenv import BUILD
    require_native()
    tool = REPO / "tools" / "platform_zip.py"
    proc = subprocess.run([sys.executable, str(tool), "--platform", "linux-x64", "--build-dir", str(BUILD),
                           "--out-dir", str(tmp_path)], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    tag = f"cp{sys.version_info[0]}{sys.version_info[1]}"
    zips = sorted(tmp_path.glob("*.zip"))
    assert [z.name for z in zips] == [f"atlas_defrag-0.1.0-linux-x64-{tag}.zip"], zips
    with zipfile.ZipFile(zips[0]) as z:
        assert 'platforms = ["linux-x64"]' in z.read("atlas_defrag/blender_manifest.toml").decode()
        assert any(n.startswith("atlas_defrag/_native") for n in z.namelist())
    blender_ext = Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    check = subprocess.run([sys.executable, str(blender_ext), "validate", str(zips[0])], capture_output=True,
                           text=True, timeout=120)
    assert check.returncode == 0, check.stdout + check.stderr
    wrong = subprocess.run([sys.executable, str(tool), "--platform", "windows-x64", "--build-dir", str(BUILD),
                            "--out-dir", str(tmp_path / "wrong")], capture_output=True, text=True, timeout=900)
    assert wrong.returncode != 0 and "built for linux-x64" in wrong.stderr, wrong.stderr[-2000:]
