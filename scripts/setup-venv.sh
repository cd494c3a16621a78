#!/usr/bin/env bash
# Create .venv/ in the repository root if it is missing and install ginn into it (editable, with
# the `dev` extra: the test suite, its lint, the sweep and persistent-homology extras).
#
# torch: where none is importable in the venv, `torch==$GINN_TORCH_VERSION` (default 2.13.0) is
# installed first, from $GINN_TORCH_INDEX when set (e.g. https://download.pytorch.org/whl/cpu, the
# CPU build from PyTorch's wheel index) and otherwise from pip's configured index. A torch that is
# already in the venv (a CUDA build, say) is kept: ginn's own requirement `torch>=2.5` accepts it.
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
    index=()
    if [[ -n ${GINN_TORCH_INDEX:-} ]]; then
        index=(--index-url "$GINN_TORCH_INDEX")
    fi
    .venv/bin/python -m pip install -q "${index[@]}" "torch==${GINN_TORCH_VERSION:-2.13.0}"
fi
.venv/bin/python -m pip install -q -e ".[${EXTRAS}]"
touch "$stamp"
