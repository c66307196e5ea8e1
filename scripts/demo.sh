#!/usr/bin/env bash
# The main job on a bundled real scan (the Meshroom one by default): the Blender
# batch entry writes a defragmented GLB, then the command-line entry measures
# the same job (charts, seams, texels, colour PSNR) and writes OBJ+MTL+PNG.
set -euo pipefail
cd "$(dirname "$0")/.."
scan="${1:-../shared/models/meshroom_esp32cam/texturedMesh.obj}"
name="$(basename "${scan%.*}")"
mkdir -p out
blender --background --factory-startup --python-exit-code 1 \
  --python build/addon/atlas_defrag/batch.py -- "$scan" "out/$name.glb" --report "out/$name.json" 2>&1 |
  grep '^atlas_defrag:'
PYTHONPATH="${ATLAS_BUILD_DIR:-build}/addon" .venv/bin/python tools/defrag_scan.py "$scan" "out/${name}_cli" --metrics
