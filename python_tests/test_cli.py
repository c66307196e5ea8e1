"""The command-line entry, tools/defrag_scan.py, run as users run it: on a real
scan, without Blender, and its output read back from disk."""
import subprocess
import sys
from pathlib import Path

import numpy as np

CLI = Path(__file__).resolve().parent.parent / "tools" / "defrag_scan.py"


def test_cli_output_loads_back_flip_free_with_the_colours_kept(native, scans, scan_path, tool_env, tmp_path):
    import scan_io

    source = scan_path("tetra")
    run = subprocess.run([sys.executable, str(CLI), str(source), str(tmp_path)],
                         capture_output=True, text=True, timeout=300, env=tool_env)
    assert run.returncode == 0, run.stderr
    assert "159 -> " in run.stdout and "PSNR" in run.stdout

    scan, written = scans("tetra"), scan_io.load(tmp_path / f"{source.stem}_defrag.obj")
    assert np.array_equal(written.triangles, scan.triangles)
    assert np.allclose(written.positions, scan.positions, rtol=1e-8, atol=1e-12)  # written with 9 digits
    assert (written.face_page >= 0).all() and len(written.page_images) >= 1
    m = native.measure(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                       written.uvs, written.face_page, written.page_sizes)
    assert m["new"]["flipped_faces"] == 0 and m["new"]["overlap_texels"] == 0
    # Through the PNG files: rows upside down or channels mixed would not pass.
    old = [np.ascontiguousarray(scan_io.load_image(p)[:, :, :3]) for p in scan.page_images]
    new = [np.ascontiguousarray(scan_io.load_image(p)[:, :, :3]) for p in written.page_images]
    fidelity = native.compare_colors(scan.positions, scan.triangles, scan.uvs, scan.face_page, old,
                                     written.uvs, written.face_page, new, samples=100000)
    assert fidelity["psnr_db"] > 38
