#!/usr/bin/env bash
# agent-perceptive, an agent that sees the ground (issue 60), as docs/agent-perceptive.md pre-registers it:
#   1. the ablation's six runs, 2e7 env steps each, two at a time: (c) scan-critic 150 with (b) scan 150,
#      (a) blind-curriculum 150 with (c) 215, (b) 215 with (a) 215 (about 3.5 h a pair on 2 cores);
#   2. the held-out rule among the arms, on examples/perceptive/heldout-ground.json, against agent-robust's
#      seeds 150 and 215 (also on agent-robust's own training ground);
#   3. where the choice stands, the winner's seeds 345 and 556: agent-perceptive's four seeds;
#   4. every run on the thesis and harder courses, the stair sweep, the default and the balanced push sweeps
#      and the friction sweep, beside agent-robust, agent-rp, the kernel and the expert (none of it chooses
#      anything), the report, and the faces of the top-of-trunk pushes.
# Every step resumes where it stopped and a finished one is not redone: after an interruption run this
# again. One SIGTERM (or Ctrl-C) to this script passes on to the running commands, which checkpoint.
#
#   nohup examples/perceptive/agent-perceptive.sh >> runs/agent-perceptive.log 2>&1 &
#
# RUNS (default runs) holds the runs, EVAL (default evaluations/perceptive) the evaluation records, REPORT
# (default docs/results/perceptive) the tables and plots. COMMITTED (default training/perceptive) holds the
# run folders a session committed unfinished (config, logs, last checkpoint, policy); one not yet in
# RUNS/perceptive is copied there first, and goes on where it stopped; COMMITTED/agent-perceptive holds the
# winner's seed folders the same way.
set -euo pipefail
HERE=$(dirname "$0")
ROOT=$(cd "$HERE/../.." && pwd)
RUNS=${RUNS:-runs}
R=$RUNS/perceptive
PERCEPTIVE=$RUNS/agent-perceptive
EVAL=${EVAL:-evaluations/perceptive}
REPORT=${REPORT:-docs/results/perceptive}
ROBUST="$ROOT/src/krl/agent/policies/agent-robust/seed[12]*.npz"  # agent-robust's 150, 215
ROBUST_GROUND=$ROOT/training/robust/sym-curriculum-seed150/config.json
COMMITTED=${COMMITTED:-$ROOT/training/perceptive}

# shellcheck source=../gait/together.sh
source "$HERE/../gait/together.sh"

restore "$COMMITTED" "$R" agent-perceptive
restore "$COMMITTED/agent-perceptive" "$PERCEPTIVE"

# 1. the arms, two runs at a time
train() { echo "krl agent train --out $R/$1-seed$2 --seed $2 --config $HERE/$1.json --quiet"; }
together "$(train scan-critic 150)" "$(train scan 150)"
together "$(train blind-curriculum 150)" "$(train scan-critic 215)"
together "$(train scan 215)" "$(train blind-curriculum 215)"

# 2. the rule
together "krl agent heldout --policy 'agent-robust=$ROBUST' --policy 'blind-curriculum=$R/blind-curriculum-seed*' \
--policy 'scan=$R/scan-seed*' --policy 'scan-critic=$R/scan-critic-seed*' \
--env $HERE/heldout-ground.json --choose blind-curriculum,scan,scan-critic --baseline agent-robust \
--baseline-env $ROBUST_GROUND --episodes 32 --out $R/heldout-perceptive --seed-group $PERCEPTIVE --quiet"
stands=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["baseline"]["stands"])' \
  "$R/heldout-perceptive/choice.json")
echo "the choice stands against agent-robust: $stands"

# 3. the winner's other two seeds
if [ "$stands" = "True" ]; then
  CHOSEN=$R/heldout-perceptive/chosen-config.json
  together "krl agent train --out $PERCEPTIVE/seed345 --seed 345 --config $CHOSEN --quiet" \
    "krl agent train --out $PERCEPTIVE/seed556 --seed 556 --config $CHOSEN --quiet"
fi
controllers=""
for arm in blind-curriculum scan scan-critic; do controllers+=" --controller 'agent:$R/$arm-seed*'"; done
if [ "$stands" = "True" ]; then controllers="--controller agent:$PERCEPTIVE$controllers"; fi
controllers+=" --controller agent:robust --controller agent --controller kernel:ext --controller expert"

# 4. the evaluation, the baselines' records copied from agent-robust's (same files by hash); a run evaluated
# already is not run again
for baseline in agent-robust agent-rp expert-stance0.2; do
  if [ -d "$ROOT/evaluations/robust/$baseline" ] && [ ! -e "$EVAL/$baseline" ]; then
    mkdir -p "$EVAL" && cp -r "$ROOT/evaluations/robust/$baseline" "$EVAL/$baseline"
  fi
done
together "krl evaluate $controllers --course thesis --course harder --stair-sweep --push-sweep --attempts 50 \
--friction-sweep --out $EVAL --quiet"
together "krl evaluate $controllers --push-sweep --push-directions balanced --attempts 48 --out $EVAL-balanced --quiet"
together "krl report --results $EVAL --out $REPORT"
together "krl report --results $EVAL-balanced --out $REPORT-balanced"
together "krl analyze push-sweep $EVAL-balanced --out $REPORT-balanced/push-faces"
