#!/usr/bin/env bash
# agent-gait, krl's gait-driving agent, from nothing (docs/agent-gait.md):
#   1. the gait ablation: five variants x seeds 150 and 215, 2e7 env steps each (about 10 h on 2 cores);
#   2. the choice among the driving variants on held-out episodes of the training distribution (never on a
#      course): `krl agent heldout --choose`, which writes the chosen recipe's config;
#   3. that recipe's seeds 345 and 556, at once (about 2 h); with the ablation's two, agent-gait's four seeds;
#   4. agent-gait, the other variants and the baselines (agent-rp, the MPC expert, kernel-base) on the
#      thesis's and the harder courses, the push sweep (50 attempts a force, with directions) and the
#      friction sweep, then the report.
# Every step resumes where it stopped and a finished one is not redone: after an interruption run this
# again. One SIGTERM (or Ctrl-C) to this script passes on to the running commands, which checkpoint.
#
#   nohup examples/gait/agent-gait.sh > runs/agent-gait.log 2>&1 &
#
# RUNS (default runs) holds the runs, EVAL (default evaluations/gait) the evaluation records, REPORT
# (default docs/results/gait) the tables and plots.
set -euo pipefail
RUNS=${RUNS:-runs}
EVAL=${EVAL:-evaluations/gait}
REPORT=${REPORT:-docs/results/gait}
ABLATION=$RUNS/agent-studies/gait-ablation
TRIALS=$ABLATION/trials/list
HELDOUT=$RUNS/heldout-gait
GAIT=$RUNS/agent-gait
VARIANTS=(residual-ext heights rhythm both steer-both)
DRIVING=heights,rhythm,both,steer-both

# shellcheck source=together.sh
source "$(dirname "$0")/together.sh"

together "krl agent study gait-ablation --out $ABLATION --seeds 150,215 --jobs 2 --quiet"

policies=""
for variant in "${VARIANTS[@]}"; do policies+=" --policy '$variant=$TRIALS/$variant-seed*'"; done
# the ablation's runs of the chosen variant join the seed group $GAIT as two of agent-gait's seeds
together "krl agent heldout$policies --episodes 32 --choose $DRIVING --out $HELDOUT --seed-group $GAIT --quiet"
chosen=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["chosen"])' "$HELDOUT/choice.json")
echo "chosen on held-out episodes: $chosen"

together \
  "krl agent train --out $GAIT/seed345 --seed 345 --config $HELDOUT/chosen-config.json --quiet" \
  "krl agent train --out $GAIT/seed556 --seed 556 --config $HELDOUT/chosen-config.json --quiet"

# the baselines' records of the four-seed evaluation (same files by hash), so only what is new runs
for baseline in agent-rp expert-stance0.2 kernel-base; do
  if [ -d "evaluations/four-seeds/$baseline" ] && [ ! -e "$EVAL/$baseline" ]; then
    mkdir -p "$EVAL" && cp -r "evaluations/four-seeds/$baseline" "$EVAL/$baseline"
  fi
done
# the chosen variant's files are two of agent-gait's: krl evaluate runs them once, for both labels
controllers="--controller agent:$GAIT"
for variant in "${VARIANTS[@]}"; do controllers+=" --controller 'agent:$TRIALS/$variant-seed*'"; done
controllers+=" --controller agent --controller expert --controller kernel"
together "krl evaluate $controllers --course thesis --course harder --push-sweep --attempts 50 \
--friction-sweep --out $EVAL --quiet"
together "krl report --results $EVAL --out $REPORT"
