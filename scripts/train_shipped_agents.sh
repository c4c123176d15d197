#!/usr/bin/env bash
# Train the agents shipped in trained_agents/ (SAC and PPO on CircleTrack-v0 case 1, case 2 and
# Transport-v0 goal=paper, velocity mode) in two parallel lanes, then package them.
#
#   scripts/train_shipped_agents.sh            # train into runs/shipped/<name>/ (logs in runs/shipped/logs/),
#                                              # then package them
#   scripts/train_shipped_agents.sh sac        # only the three SAC agents, all at once (as they were trained)
#   scripts/train_shipped_agents.sh package    # copy the runs into trained_agents/<name>/ (scripts.ship_agent)
#   .venv/bin/python -m scripts.evaluate_shipped  # evaluation.json of each agent + campc/random references
#
# Hyperparameters come from train_configs/{ppo,sac}.yml (uvdms entries); the budgets below override
# n_timesteps. Seed 0: training envs use seeds 0 and 1, the evaluation callback seeds 1000000+
# (agents/training/train.py). The shipped agents are evaluated on seeds 1000-1009 (README, "Train an agent").
# A run whose directory already exists is skipped (resume it with `uvdms train --resume DIR`).
# The machine has 2 cores: two lanes, nice 10, torch.set_num_threads(1) (agents.training.train does that).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
OUT=${OUT:-runs/shipped}
SEED=${SEED:-0}
PPO_STEPS=${PPO_STEPS:-300000}
SAC_STEPS=${SAC_STEPS:-150000}
mkdir -p "$OUT/logs"

# name algo env env-kwargs budget
AGENTS_A=(
  "ppo-circle-case1-v0 ppo uvdms/CircleTrack-v0 case=1 $PPO_STEPS"
  "ppo-circle-case2-v0 ppo uvdms/CircleTrack-v0 case=2 $PPO_STEPS"
  "ppo-transport-paper-v0 ppo uvdms/Transport-v0 goal=paper $PPO_STEPS"
)
AGENTS_B=(
  "sac-circle-case1-v0 sac uvdms/CircleTrack-v0 case=1 $SAC_STEPS"
  "sac-circle-case2-v0 sac uvdms/CircleTrack-v0 case=2 $SAC_STEPS"
  "sac-transport-paper-v0 sac uvdms/Transport-v0 goal=paper $SAC_STEPS"
)

run_one() {
  local name=$1 algo=$2 env=$3 kw=$4 steps=$5
  if [[ -d "$OUT/$name" ]]; then
    echo "[$(date -u +%FT%TZ)] skip $name ($OUT/$name exists)" >> "$OUT/logs/lanes.log"
    return 0
  fi
  echo "[$(date -u +%FT%TZ)] start $name" >> "$OUT/logs/lanes.log"
  nice -n 10 "$PY" -m agents.training.train --algo "$algo" --env "$env" --env-kwargs "$kw" --seed "$SEED" \
    --total-timesteps "$steps" --out "$OUT/$name" --no-progress > "$OUT/logs/$name.log" 2>&1 ||
    echo "FAILED $name" >> "$OUT/logs/lanes.log"
  echo "[$(date -u +%FT%TZ)] end $name" >> "$OUT/logs/lanes.log"
}

lane() {
  for spec in "$@"; do
    # shellcheck disable=SC2086
    run_one $spec
  done
}

if [[ "${1:-train}" == "package" ]]; then
  for spec in "${AGENTS_A[@]}" "${AGENTS_B[@]}"; do
    read -r name algo _ _ _ <<< "$spec"
    if ! compgen -G "$OUT/$name/*/${algo}_$SEED" > /dev/null; then
      echo "no run for $name in $OUT: trained_agents/$name left as it is" >&2
      continue
    fi
    "$PY" -m scripts.ship_agent "$OUT/$name"/*/"${algo}_$SEED" "trained_agents/$name" --which "${WHICH:-best}" --overwrite
  done
  exit 0
fi

case "${1:-train}" in
  train) lane "${AGENTS_A[@]}" & lane "${AGENTS_B[@]}" & wait ;;
  # The shipped SAC agents (action_scale 0.3) were trained later than the PPO ones, the three at once:
  sac) for spec in "${AGENTS_B[@]}"; do lane "$spec" & done; wait ;;
  *) echo "usage: $0 [train|sac|package]" >&2; exit 2 ;;
esac
"$0" package
