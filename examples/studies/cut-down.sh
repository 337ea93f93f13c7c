#!/usr/bin/env bash
# Chapter 4's agent studies at the cut-down budget of docs/studies.md ("What this 2-core machine runs"):
# 6e7 env steps in all, 5.2 h on 2 cores with --jobs 2 (measured). Every study resumes where it stopped,
# and a finished trial is never re-run, so after an interruption run this again. Then the reports go to
# docs/results/agent.
#
#   nohup examples/studies/cut-down.sh --jobs 2 > runs/cut-down.log 2>&1 &
#
# OUT and REPORT may be set in the environment; any other `krl agent study` option (--storage for many
# machines, --jobs) is passed on: examples/studies/cut-down.sh --storage postgresql://...
set -euo pipefail
OUT=${OUT:-runs/agent-studies}
REPORT=${REPORT:-docs/results/agent}
SEEDS=150,215
study() {
  local name=$1
  shift
  krl agent study "$name" --out "$OUT/$name" --config examples/studies/cut-down.json --quiet "$@"
}

# the search without pruning, so its report can replay the median pruner on whole curves
study ppo-search --trials 16 --budget 500000 --top 3 --seeds "$SEEDS" --confirm-budget 1000000 --pruner none "${@}"
study reward-features --seeds "$SEEDS" --budget 500000 "${@}"
# the same on the final agent's ground (rough height field, hills, pushes), where training falls: on our
# reading of the optimisation terrain nothing falls, so the fall penalty of trials 5 and 7 cannot act
krl agent study reward-features --out "$OUT/reward-features-rough" --config examples/studies/cut-down-rough.json \
  --quiet --seeds "$SEEDS" --budget 500000 "${@}"
study reward-rbf --trials 10 --budget 500000 --top 2 --seeds "$SEEDS" --confirm-budget 500000 "${@}"
study reward-weights --trials 10 --budget 500000 --top 2 --seeds "$SEEDS" --confirm-budget 500000 "${@}"
study state-space --seeds "$SEEDS" --budget 500000 "${@}"
study alternative --seeds "$SEEDS" --budget 1000000 "${@}"

for name in ppo-search reward-features reward-rbf reward-weights state-space alternative; do
  krl agent study "$name" --out "$OUT/$name" --report --report-out "$REPORT" "${@}"
done
krl agent study reward-features --out "$OUT/reward-features-rough" --report --report-out "$REPORT/rough" "${@}"
krl agent study level-base --report-out "$REPORT"
