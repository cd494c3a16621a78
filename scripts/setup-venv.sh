#!/usr/bin/env bash
# Create .venv/ in the repository root if it is missing and install ginn into it (editable, with
# the `dev` extra: the test suite, its lint, and the sweep, postgres, track and pardiso extras).
#
# The installer is uv (itself installed with pip into the venv), which installs and compiles the
# dependencies in parallel; where it cannot (no uv for this platform, say), pip does the same.
#
# torch: where none is importable in the venv, `torch==$GINN_TORCH_VERSION` (default 2.13.0) is
# installed first, from $GINN_TORCH_INDEX when set (e.g. https://download.pytorch.org/whl/cpu, the
# CPU build from PyTorch's wheel index), else from the wheel folders of pip's configuration
# (`find-links`) or pip's configured index. A torch that is already in the venv (a CUDA build,
# say) is kept: ginn's own requirement `torch>=2.5` accepts it.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/torch-source.sh
PY=${PYTHON:-python3}
EXTRAS=${GINN_EXTRAS:-dev}
TORCH="torch==${GINN_TORCH_VERSION:-2.13.0}"
if [[ ! -x .venv/bin/python ]]; then
    "$PY" -m venv .venv
fi
stamp=.venv/.ginn-installed
if [[ -f $stamp && $stamp -nt pyproject.toml ]]; then
    exit 0
fi
pip=(.venv/bin/python -m pip install -q)

with_uv() {
    "${pip[@]}" uv >/dev/null 2>&1 || return 1
    local uv=(.venv/bin/uv pip install -q --compile-bytecode --python .venv/bin/python)
    if ! .venv/bin/python -c "import torch" >/dev/null 2>&1; then
        torch_source
        "${uv[@]}" "${TORCH_SOURCE[@]}" "$TORCH" || return 1
    fi
    "${uv[@]}" -e ".[${EXTRAS}]"
}

with_pip() {
    "${pip[@]}" --upgrade pip >/dev/null 2>&1 || true
    if ! .venv/bin/python -c "import torch" >/dev/null 2>&1; then
        local index=()
        if [[ -n ${GINN_TORCH_INDEX:-} ]]; then
            index=(--index-url "$GINN_TORCH_INDEX")
        fi
        "${pip[@]}" "${index[@]}" "$TORCH"
    fi
    "${pip[@]}" -e ".[${EXTRAS}]"
}

if ! with_uv; then
    echo "uv could not install the dependencies; installing them with pip"
    with_pip
fi
touch "$stamp"
