#!/usr/bin/env bash
# Create .venv/ in the repository root if it is missing and install ginn into it (editable).
# Where no torch is importable in the venv, install the CPU build first so that a CPU machine
# never pulls a multi-GB CUDA build through the plain `torch>=...` requirement.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
EXTRAS=${GINN_EXTRAS:-dev}
if [[ ! -x .venv/bin/python ]]; then
    "$PY" -m venv .venv
fi
stamp=.venv/.ginn-installed
if [[ -f $stamp && $stamp -nt pyproject.toml ]]; then
    exit 0
fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
if ! .venv/bin/python -c "import torch" >/dev/null 2>&1; then
    .venv/bin/python -m pip install -q "torch==${GINN_TORCH_VERSION:-2.13.0}"
fi
.venv/bin/python -m pip install -q -e ".[${EXTRAS}]"
touch "$stamp"
