# SPDX-License-Identifier: MIT
"""The interactive path (dialog, modal worker, Esc, undo) in a real Blender 3.4
window under Xvfb, with simulated events."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest

import blhelp as H
from blenv import ADDON_PARENT, BLENDER, HERE, require_blender, require_native


@pytest.fixture(scope="module")
def gui_result(tmp_path_factory):
    require_native()
    require_blender()
    H.model_path("tetra")  # skips when the scan is missing
    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run is not installed (apt-get install xvfb xauth)")
    out = tmp_path_factory.mktemp("gui") / "result.json"
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", BLENDER, "--factory-startup", "--enable-event-simulate",
           "--python", str(HERE / "bl_gui.py"), "--", "--addon-parent", str(ADDON_PARENT), "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    try:
        data = json.loads(out.read_text())
    except (OSError, ValueError):
        data = {"steps": {}}
    data["log"] = (proc.returncode, proc.stdout[-3000:], proc.stderr[-3000:])
    return data


@pytest.mark.parametrize("step", ["modal_run_and_undo", "escape_cancels", "dialog_run", "modal_one_atlas",
                                  "redo_run_again", "dialog_default_maps"])
def test_gui(gui_result, step):
    assert gui_result.get("background") is False, gui_result["log"]
    res = gui_result["steps"].get(step)
    assert res is not None, gui_result["log"]
    assert res["ok"], res["info"]
    assert "driver" not in gui_result["steps"], gui_result["steps"]["driver"]
