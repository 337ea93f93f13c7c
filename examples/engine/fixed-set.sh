#!/usr/bin/env bash
# The fixed set of runs on which issue 46 checks that a change to the episode engine keeps every record:
# every shipped controller (the expert at both stance times, both kernels, the four agents' seed 150) on
# the thesis's and the harder courses and the flat course, and 100 push attempts each (10 forces x 10).
# Run it with the code before the change and with the code after it, then compare:
#
#   git worktree add /tmp/before <commit before the change>
#   (cd /tmp/before && PYTHONPATH=src examples/engine/fixed-set.sh /tmp/fixed-before)
#   examples/engine/fixed-set.sh /tmp/fixed-after
#   krl compare-results /tmp/fixed-before /tmp/fixed-after
#
# OUT (the first argument) receives the records; WORKERS (default: every core) the processes. A run stopped
# part-way resumes when started again with the same OUT.
set -euo pipefail
OUT=${1:?usage: fixed-set.sh OUT}
WORKERS=${WORKERS:-$(nproc)}
CONTROLLERS=(--controller expert --controller expert:stance=0.3 --controller kernel --controller kernel:ext
  --controller agent --controller agent:base --controller agent:gait --controller agent:gait-ground)
krl evaluate "${CONTROLLERS[@]}" --seeds 150 --course thesis --course harder --course flat \
  --push-sweep --magnitudes 250,325,400,475,550,625,700,775,850,900 --attempts 10 \
  --workers "$WORKERS" --out "$OUT" --quiet
