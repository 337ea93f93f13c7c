#!/usr/bin/env bash
# agent-robust, a mirror-symmetric, push-hardened agent (issue 45), as docs/agent-robust.md pre-registers it:
#   1. the pilot: agent-gait-ground's recipe with symmetry augment and with loss, seed 150, to 4e6 env
#      steps side by side; the held-out rule chooses S, and the winner's run goes on as sym's seed 150;
#   2. the candidate arms, 2e7 env steps, seeds 150 and 215, two runs at a time: sym, curriculum and
#      sym-curriculum (about 12 h on 2 cores);
#   3. the held-out rule among them against agent-gait-ground's seeds 150 and 215; where the choice stands,
#      its seeds 345 and 556: agent-robust's four seeds;
#   4. every run on the thesis and harder courses, the default and the balanced push sweeps and the friction
#      sweep, beside agent-gait-ground, agent-rp and the expert, then the report;
#   5. sample efficiency: each arm's training success curve against its reference's final level;
#   6. rp-sym (agent-rp's recipe with S, 2 seeds), which nothing above reads, then its evaluation (the runs
#      evaluated already are not run again), the report again and its curve;
#   7. where agent-robust was trained, left and right measured again: the balanced sweep at 350-600 N with
#      400 attempts per force (100 distinct pushes per quarter), beside agent-gait-ground and the expert.
# Every step resumes where it stopped and a finished one is not redone: after an interruption run this
# again. One SIGTERM (or Ctrl-C) to this script passes on to the running commands, which checkpoint.
#
#   nohup examples/robust/agent-robust.sh > runs/agent-robust.log 2>&1 &
#
# RUNS (default runs) holds the runs, EVAL (default evaluations/robust) the evaluation records, REPORT
# (default docs/results/robust) the tables and plots. COMMITTED (default training/robust) holds the run
# folders a session committed unfinished (config, logs, last checkpoint, policy); one not yet in
# RUNS/robust is copied there first, and goes on where it stopped; COMMITTED/agent-robust holds
# agent-robust's own seed folders the same way, copied to RUNS/agent-robust.
set -euo pipefail
HERE=$(dirname "$0")
ROOT=$(cd "$HERE/../.." && pwd)
RUNS=${RUNS:-runs}
EVAL=${EVAL:-evaluations/robust}
REPORT=${REPORT:-docs/results/robust}
R=$RUNS/robust
ROBUST=$RUNS/agent-robust
PILOT_STEPS=4000000
BASELINE="$ROOT/src/krl/agent/policies/agent-gait-ground/seed[12]*.npz"  # agent-gait-ground's 150, 215
GROUND_CONFIG=$ROOT/training/agent-gait-ground-seed345/config.json

COMMITTED=${COMMITTED:-$ROOT/training/robust}

# shellcheck source=../gait/together.sh
source "$HERE/../gait/together.sh"

restore "$COMMITTED" "$R" agent-robust
restore "$COMMITTED/agent-robust" "$ROBUST"

# 1. the pilot, and S
if [ ! -e "$R/heldout-pilot/choice.json" ]; then
  together \
    "krl agent train --out $R/pilot-augment-seed150 --seed 150 --config $HERE/gait-ground-augment.json \
--steps $PILOT_STEPS --quiet" \
    "krl agent train --out $R/pilot-loss-seed150 --seed 150 --config $HERE/gait-ground-loss.json \
--steps $PILOT_STEPS --quiet"
  together "krl agent heldout --policy augment=$R/pilot-augment-seed150 --policy loss=$R/pilot-loss-seed150 \
--choose augment,loss --episodes 32 --out $R/heldout-pilot --quiet"
fi
S=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["chosen"])' "$R/heldout-pilot/choice.json")
echo "the pilot's symmetry: $S"
if [ -d "$R/pilot-$S-seed150" ] && [ ! -e "$R/sym-seed150" ]; then mv "$R/pilot-$S-seed150" "$R/sym-seed150"; fi

# the arms' configs: S on agent-gait-ground's recipe (the pilot's chosen config), with the curriculum, and
# on agent-rp's recipe
mkdir -p "$R/configs"
python3 - "$R" "$S" "$HERE" "$ROOT" <<'PY'
import json, sys
runs, symmetry, here, root = sys.argv[1:]
def write(name, config):
    with open(f"{runs}/configs/{name}.json", "w") as file:
        json.dump(config, file, indent=2)
sym = json.load(open(f"{runs}/heldout-pilot/chosen-config.json"))
write("sym", sym)
curriculum = json.load(open(f"{here}/gait-ground-curriculum.json"))
write("sym-curriculum", {**sym, "env": curriculum["env"]})
rp = json.load(open(f"{root}/training/agent-rp-seed150/config.json"))
write("rp-sym", {**rp, "ppo": {**rp["ppo"], "symmetry": symmetry}})
PY

# 2. the candidate arms, two runs at a time
train() { echo "krl agent train --out $R/$1-seed$2 --seed $2 --config $3 --quiet"; }
together "$(train sym 150 "$R/configs/sym.json")" "$(train sym 215 "$R/configs/sym.json")"
together "$(train curriculum 150 "$HERE/gait-ground-curriculum.json")" \
  "$(train curriculum 215 "$HERE/gait-ground-curriculum.json")"
together "$(train sym-curriculum 150 "$R/configs/sym-curriculum.json")" \
  "$(train sym-curriculum 215 "$R/configs/sym-curriculum.json")"

# 3. the rule: on the broad push ground, against agent-gait-ground's seeds 150 and 215
together "krl agent heldout --policy 'baseline=$BASELINE' --policy 'sym=$R/sym-seed*' \
--policy 'curriculum=$R/curriculum-seed*' --policy 'sym-curriculum=$R/sym-curriculum-seed*' \
--env $HERE/broad-pushes.json --choose sym,curriculum,sym-curriculum --baseline baseline \
--baseline-env $GROUND_CONFIG --episodes 32 --out $R/heldout-robust \
--seed-group $ROBUST --quiet"
stands=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["baseline"]["stands"])' \
  "$R/heldout-robust/choice.json")
echo "the choice stands against agent-gait-ground: $stands"
controllers=""
for arm in sym curriculum sym-curriculum; do controllers+=" --controller 'agent:$R/$arm-seed*'"; done
if [ "$stands" = "True" ]; then
  together \
    "krl agent train --out $ROBUST/seed345 --seed 345 --config $R/heldout-robust/chosen-config.json --quiet" \
    "krl agent train --out $ROBUST/seed556 --seed 556 --config $R/heldout-robust/chosen-config.json --quiet"
  controllers="--controller agent:$ROBUST$controllers"
fi
controllers+=" --controller agent:gait-ground --controller agent --controller expert"

# 4. the evaluation of the controllers in $1, the baselines' records copied from agent-gait-ground's (same
# files by hash); a run evaluated already is not run again
for baseline in agent-gait-ground agent-rp expert-stance0.2; do
  if [ -d "$ROOT/evaluations/gait/$baseline" ] && [ ! -e "$EVAL/$baseline" ]; then
    mkdir -p "$EVAL" && cp -r "$ROOT/evaluations/gait/$baseline" "$EVAL/$baseline"
  fi
done
evaluate() {
  together "krl evaluate $1 --course thesis --course harder --push-sweep --attempts 50 --friction-sweep \
--out $EVAL --quiet"
  together "krl evaluate $1 --push-sweep --push-directions balanced --attempts 48 --out $EVAL-balanced --quiet"
  together "krl report --results $EVAL --out $REPORT"
  together "krl report --results $EVAL-balanced --out $REPORT-balanced"
}
evaluate "$controllers"

# 5. sample efficiency (docs/agent-robust.md): the env steps at which each arm's mean training success reaches
# its reference's final one: the gait-ground arms against agent-gait-ground's seeds 150 and 215, rp-sym against
# agent-rp's seeds 345 and 556 (the two whose logs hold the success rate)
GROUND_RUNS=$ROOT/training/agent-studies/gait-ground/trials/list
group() { echo "--group $1=$R/$1-seed150,$R/$1-seed215"; }
together "krl agent curves --group baseline=$GROUND_RUNS/pyramids-pushes-seed150,$GROUND_RUNS/pyramids-pushes-seed215 \
$(group sym) $(group curriculum) $(group sym-curriculum) --reach baseline --out $REPORT/curves"
# 6. the faithful recipe with S: reported beside the arms, not a candidate; evaluated the same way
together "$(train rp-sym 150 "$R/configs/rp-sym.json")" "$(train rp-sym 215 "$R/configs/rp-sym.json")"
evaluate "$controllers --controller 'agent:$R/rp-sym-seed*'"
together "krl agent curves --group agent-rp=$ROOT/training/agent-rp-seed345,$ROOT/training/agent-rp-seed556 \
$(group rp-sym) --reach agent-rp --out $REPORT/curves-rp"
# 7. left and right at the target's forces, with 100 distinct pushes per side (docs/agent-robust.md)
if [ "$stands" = "True" ]; then
  together "krl evaluate --controller agent:$ROBUST --controller agent:gait-ground --controller expert \
--push-sweep --push-directions balanced --magnitudes 350:600:50 --attempts 400 --out $EVAL-left-right --quiet"
  together "krl report --results $EVAL-left-right --out $REPORT-left-right"
fi
