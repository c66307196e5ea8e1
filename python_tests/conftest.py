"""Shared fixtures: the built native module and the real scans in ../shared/models.

Locations (environment overrides): ATLAS_BUILD_DIR, the CMake build folder
(default <repo>/build); ATLAS_MODELS_DIR, the shared scans (default
<repo>/../shared/models). Tests of a missing scan skip, saying which.
"""
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build"))
MODELS = Path(os.environ.get("ATLAS_MODELS_DIR", REPO.parent / "shared" / "models"))
# The package as built (with its native module), and the bpy-free tools.
IMPORT_PATH = [str(BUILD / "addon"), str(REPO / "tools")]
sys.path[:0] = IMPORT_PATH

SCANS = {
    "meshroom": MODELS / "meshroom_esp32cam" / "texturedMesh.obj",
    "smithsonian": MODELS / "smithsonian_usnm1145291" / "usnm_1145291.glb",
    "tetra": MODELS / "tetra_miniature" / "teTra-Mk5-miniature-model.obj",
}


def require_scan(name: str) -> Path:
    path = SCANS[name]
    if not path.is_file():
        pytest.skip(f"real scan {path} is missing (the shared models; set ATLAS_MODELS_DIR)")
    return path


@pytest.fixture(scope="session")
def native():
    from atlas_defrag import _native

    return _native


@pytest.fixture(scope="session")
def tool_env():
    """Environment for running the tools as users do: the build on PYTHONPATH."""
    return dict(os.environ, PYTHONPATH=os.pathsep.join(IMPORT_PATH))


@pytest.fixture(scope="session")
def scan_path():
    """The file of a real scan, by its name in SCANS; skips if it is missing."""
    return require_scan


@pytest.fixture(scope="session")
def scans():
    import scan_io

    cache = {}

    def load(name):
        if name not in cache:
            cache[name] = scan_io.load(require_scan(name))
        return cache[name]

    return load


@pytest.fixture(scope="session")
def defragmented(native, scans):
    """(scan, native.defragment result with default options) of a real scan,
    computed once per session for every test that looks at it."""
    cache = {}

    def run(name):
        if name not in cache:
            scan = scans(name)
            cache[name] = scan, native.defragment(scan.positions, scan.triangles, scan.uvs,
                                                  scan.face_page, scan.page_sizes)
        return cache[name]

    return run
