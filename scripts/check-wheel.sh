#!/usr/bin/env bash
# The package as pip users get it: build ginn's wheel, install it without extras into a fresh
# virtual environment, and run the main job's commands (train, eval, export, view) from a folder
# outside the repository. `.ci/run` calls it after `make test`; it needs `make venv` first (uv
# and pip's configuration come from .venv/).
set -euo pipefail
cd "$(dirname "$0")/.."
TORCH="torch==${GINN_TORCH_VERSION:-2.13.0}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
.venv/bin/python -m pip wheel -q --no-deps -w "$tmp/dist" . >/dev/null
wheel=$(ls "$tmp"/dist/ginn-*.whl)
python3 -m venv "$tmp/venv"
source scripts/torch-source.sh
torch_source
if [[ -x .venv/bin/uv ]]; then
    .venv/bin/uv pip install -q --python "$tmp/venv/bin/python" "${TORCH_SOURCE[@]}" "$TORCH"
    .venv/bin/uv pip install -q --python "$tmp/venv/bin/python" "$wheel"
else
    "$tmp/venv/bin/python" -m pip install -q "${TORCH_SOURCE[@]}" "$TORCH"
    "$tmp/venv/bin/python" -m pip install -q "$wheel"
fi
cd "$tmp"
ginn=("$tmp/venv/bin/ginn")
export OMP_NUM_THREADS=1
"${ginn[@]}" train obstacle --preset demo --iterations 10 --out run --quiet \
    --set sampling.n_domain=256 --set training.threads=1 --set output.resolution=64
"${ginn[@]}" eval run --resolution 64 --heldout 4 >/dev/null
"${ginn[@]}" export run --latent 0.5 --resolution 48 --out exported >/dev/null
"${ginn[@]}" view run --steps 4 >/dev/null
test -s run/metrics.json && test -s exported/verdicts.json && test -s run/figures/explorer.html
echo "the wheel without extras trains, evaluates, exports and views from $tmp"
