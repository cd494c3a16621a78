#!/usr/bin/env bash
# The bracket runs reported in docs/bracket.md (issue 9), exactly as they were run.
# Run from the repository root; each run writes runs/<name>/ (ignored by git).
set -euo pipefail
GINN=${GINN:-.venv/bin/ginn}

# 1. the cpu preset (one shape), in the background, one torch thread
nohup $GINN train bracket --preset cpu --out runs/bracket-cpu --seed 0 \
  --set training.threads=1 --quiet > runs/bracket-cpu.log 2>&1 &

# 2. Table 4 connectedness ablation at cpu scale: the same run without the connectedness loss
nohup $GINN train bracket --preset cpu --out runs/bracket-cpu-noconn --seed 0 \
  --set training.threads=1 --set losses.connectedness.weight=0 --quiet > runs/bracket-cpu-noconn.log 2>&1 &
wait
