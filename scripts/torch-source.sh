# Sourced by setup-venv.sh and check-wheel.sh: `torch_source` fills the array TORCH_SOURCE with
# where torch comes from: $GINN_TORCH_INDEX as the index when set, else the wheel folders of pip's
# configuration (`find-links`, read with .venv's pip), else nothing (pip's configured index).
torch_source() {
    TORCH_SOURCE=()
    if [[ -n ${GINN_TORCH_INDEX:-} ]]; then
        TORCH_SOURCE=(--index-url "$GINN_TORCH_INDEX")
        return
    fi
    local links
    for links in $(.venv/bin/python -m pip config get global.find-links 2>/dev/null || true); do
        TORCH_SOURCE+=(--find-links "$links")
    done
}
