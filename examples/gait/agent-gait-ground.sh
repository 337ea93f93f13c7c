#!/usr/bin/env bash
# agent-gait on ground that asks for its drives (docs/agent-gait.md, "Next: agent-gait on ground ..."):
#   1. the ground study: agent-gait's recipe with stepped pyramids (`pyramids`) and also pushes up to 600 N
#      (`pyramids-pushes`), seeds 150 and 215, 2e7 env steps each (about 4.5 h on 2 cores);
#   2. the rule written before any of its runs: of the two, the one with the higher held-out success on the
#      broad ground (pyramids-pushes' environment), which must beat agent-gait there by more than one
#      episode and be no worse than it by more than one episode on agent-gait's own ground;
#   3. if that choice stands, its seeds 345 and 556 (about 2.2 h): agent-gait-ground's four seeds;
#   4. the study's variants (and agent-gait-ground) on the courses, the harder courses, the push and the
#      friction sweeps, beside agent-gait's evaluation, then the report.
# Every step resumes where it stopped and a finished one is not redone: after an interruption run this
# again. One SIGTERM (or Ctrl-C) to this script passes on to the running commands, which checkpoint.
#
#   nohup examples/gait/agent-gait-ground.sh > runs/agent-gait-ground.log 2>&1 &
#
# RUNS (default runs) holds the runs, EVAL (default evaluations/gait, agent-gait's) the evaluation records,
# REPORT (default docs/results/gait) the tables and plots.
set -euo pipefail
RUNS=${RUNS:-runs}
EVAL=${EVAL:-evaluations/gait}
REPORT=${REPORT:-docs/results/gait}
STUDY=$RUNS/agent-studies/gait-ground
TRIALS=$STUDY/trials/list
ABLATION_TRIALS=$RUNS/agent-studies/gait-ablation/trials/list
HELDOUT=$RUNS/heldout-ground
GROUND=$RUNS/agent-gait-ground
VARIANTS=(pyramids pyramids-pushes)

# shellcheck source=together.sh
source "$(dirname "$0")/together.sh"

together "krl agent study gait-ground --out $STUDY --seeds 150,215 --jobs 2 --quiet"

# agent-gait's seeds 150 and 215 are the ablation's steer-both runs; its recipe's ground is its config's
together "krl agent heldout --policy 'agent-gait=$ABLATION_TRIALS/steer-both-seed*' \
--policy 'pyramids=$TRIALS/pyramids-seed*' --policy 'pyramids-pushes=$TRIALS/pyramids-pushes-seed*' \
--env $TRIALS/pyramids-pushes-seed150/config.json --choose pyramids,pyramids-pushes --baseline agent-gait \
--baseline-env $ABLATION_TRIALS/steer-both-seed150/config.json --episodes 32 --out $HELDOUT \
--seed-group $GROUND --quiet"
stands=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["baseline"]["stands"])' \
  "$HELDOUT/choice.json")
echo "the ground study's choice stands against agent-gait: $stands"

controllers=""
for variant in "${VARIANTS[@]}"; do controllers+=" --controller 'agent:$TRIALS/$variant-seed*'"; done
if [ "$stands" = "True" ]; then
  together \
    "krl agent train --out $GROUND/seed345 --seed 345 --config $HELDOUT/chosen-config.json --quiet" \
    "krl agent train --out $GROUND/seed556 --seed 556 --config $HELDOUT/chosen-config.json --quiet"
  controllers="--controller agent:$GROUND$controllers"
fi
together "krl evaluate $controllers --course thesis --course harder --push-sweep --attempts 50 \
--friction-sweep --out $EVAL --quiet"
together "krl report --results $EVAL --out $REPORT"
