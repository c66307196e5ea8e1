"""Shared fixtures: the built native module and the real scans in ../shared/models."""
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
BUILD = Path(os.environ.get("ATLAS_BUILD_DIR", REPO / "build"))
MODELS = Path(os.environ.get("ATLAS_MODELS_DIR", REPO.parent / "shared" / "models"))
sys.path.insert(0, str(BUILD / "addon"))
sys.path.insert(0, str(REPO / "tools"))

SCANS = {
    "meshroom": MODELS / "meshroom_esp32cam" / "texturedMesh.obj",
    "smithsonian": MODELS / "smithsonian_usnm1145291" / "usnm_1145291.glb",
    "tetra": MODELS / "tetra_miniature" / "teTra-Mk5-miniature-model.obj",
}


@pytest.fixture(scope="session")
def native():
    from atlas_defrag import _native

    return _native


@pytest.fixture(scope="session")
def scan_path():
    """The file of a real scan, by its name in SCANS."""
    return SCANS.__getitem__


@pytest.fixture(scope="session")
def scans():
    import scan_io

    cache = {}

    def load(name):
        if name not in cache:
            cache[name] = scan_io.load(SCANS[name])
        return cache[name]

    return load
