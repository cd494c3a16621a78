#!/usr/bin/env bash
# The bracket runs reported in docs/bracket.md (issue 9), exactly as they were run (2026-11-23,
# shared 2-core CPU, no GPU). Run from the repository root; each run writes runs/<name>/ (ignored by git).
set -euo pipefail
GINN=${GINN:-.venv/bin/ginn}
mkdir -p runs

# 1. the cpu preset (one shape), one torch thread
nohup $GINN train bracket --preset cpu --out runs/bracket-cpu --seed 0 \
  --set training.threads=1 --quiet > runs/bracket-cpu.log 2>&1 &

# 2. Table 4 connectedness ablation at cpu scale: the same run without the connectedness loss
nohup $GINN train bracket --preset cpu --out runs/bracket-cpu-noconn --seed 0 \
  --set training.threads=1 --set losses.connectedness.weight=0 --quiet > runs/bracket-cpu-noconn.log 2>&1 &

# 3. a variant of the cpu preset with stronger envelope / normal / eikonal weights (started 10 min
#    later, 1200 iterations to finish in the session)
nohup $GINN train bracket --preset cpu --out runs/bracket-cpu-b --seed 0 --set training.threads=1 \
  --set losses.design_region.weight=1.0 --set losses.eikonal.weight=1e-4 --set losses.normal.weight=1e-3 \
  --set training.iterations=1200 --set training.lr_decay_every=400 --quiet > runs/bracket-cpu-b.log 2>&1 &

# 4. seconds per iteration of the gpu preset on this CPU (3 iterations, no results)
$GINN train bracket --preset gpu --out /tmp/br/gpu-timing --iterations 3 --set training.threads=1 \
  --set training.log_every=1 --no-results --quiet
wait

# 5. metrics (resolution 128 in 3D), STL per shape (written by train), renders (written by train)
for r in runs/bracket-cpu runs/bracket-cpu-noconn runs/bracket-cpu-b; do $GINN eval "$r"; done
$GINN eval runs/bracket-cpu runs/bracket-cpu-noconn runs/bracket-cpu-b --table
.venv/bin/python -c "
import sys, trimesh
for p in sys.argv[1:]:
    m = trimesh.load(p); print(p, 'watertight', m.is_watertight, 'degenerate faces', int((m.area_faces < 1e-14).sum()))
" runs/bracket-cpu*/shapes/*.stl

# 6. the slow test
.venv/bin/python -m pytest -m slow tests/test_bracket_training_slow.py -q -s
