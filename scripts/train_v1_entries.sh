#!/usr/bin/env bash
# Train the learned leaderboard entries on the v1 tasks, one command per entry, and export them as
# multi-seed entries (trained_agents/<entry>/seed_<k>/, weights-only exports).
#
#   scripts/train_v1_entries.sh list                      # the entries and their settings
#   scripts/train_v1_entries.sh train ENTRY [SEED ...]    # train ENTRY's runs (default seeds 0 1 2), one after
#                                                         # the other; an interrupted run is resumed, a finished
#                                                         # one skipped; then export them
#   scripts/train_v1_entries.sh export ENTRY [SEED ...]   # only the export (best model of each run)
#
# Runs go to $OUT/<entry>/ (default runs/v1), logs to $OUT/logs/. Every run's budget is set so that it takes at
# most 60 minutes on an idle 2-core VM (README, "Learned entries"). The families:
#   sac-*                  end-to-end SAC (train_configs/sac.yml, v1 entry: action_scale 0.3)
#   residual-mpc-*         a residual of at most 0.5 (circles, TD3-prior) / 0.3 (transport, SAC) of the action range
#                          over plain `mpc`
#                          (no collision rows: whatever avoidance it shows, it learned)
#   residual-mpc-dagger-*  the residual over `mpc` fitted by DAgger to CAMPC's correction (agents/algos/dagger.py)
#   ppo-lagrangian-*       PPO-Lagrangian on info["cost"] (train_configs/ppo_lagrangian.yml), 2 envs (--vec-env rollout:
#                          each env collects its part of every rollout, agents/common/rollouts.py); the -fullrange-
#                          entries without the action_scale cap (train_configs/variants/ppo_lagrangian_full_range.yml)
# All train on the randomised tasks with hydro_randomization=0.3 (the leaderboard's held-out variants use other
# seeds); the leaderboard also runs them on the paper's fixed tasks.
set -euo pipefail
cd "$(dirname "$0")/.."
UVDMS=${UVDMS:-.venv/bin/uvdms}
OUT=${OUT:-runs/v1}
AGENTS=${AGENTS:-trained_agents}
CIRCLE="case=random hydro_randomization=0.3"
TRANSPORT="goal=random hydro_randomization=0.3"
# End-to-end learners (sac-*, ppo-lagrangian-*) train with the v1 reward's tracking term widened to track_scale
# 0.5 m: at the default 5 cm, exp(-e / 0.05) is flat beyond about 20 cm, where an untrained policy starts, and
# a first end-to-end circle run drifted to 1-1.6 m RMSE at 100k steps. PPO-Lagrangian also gets SAC's
# action_scale 0.3 (commands of a few percent of zeta_max suffice; full-range exploration hits the frame).
E2E="track_scale=0.5"
PPO_LAGRANGIAN="--vec-env rollout --hyperparams action_scale=0.3"
# Residual scales: benchmarks/residual_reach.py (CAMPC's correction of mpc clipped to a residual of scale s, random
# circles, 8 held-out seeds): contact-free 6/8 at s = 0.3, 8/8 at s = 0.5; on transport mpc and campc agree.
# The circle residual learns with TD3-prior (agents/algos/td3_prior.py: TD3+BC's actor loss toward the zero residual,
# and a 10k-step critic burn-in); SAC and plain TD3 residuals drove the arms into contacts early in training
# (README, "Learned entries"). Its training reward drops the effort term (it penalises the composed command, so
# it pulls the residual against the base) and weighs the clearance term 5x.
RESIDUAL_CIRCLE="--residual mpc --residual-scale 0.5 --hyperparams actor_warmup_steps=10000"
RESIDUAL_CIRCLE_KWARGS="effort_weight=0.0 proximity_weight=1.0"
# The same with the 36 clearance features in the residual's observation (uvdms_gym.residual.ClearanceFeatures: the
# action-space direction that opens the clearances below d2, and each clearance's rate under mpc's command): where
# the obstacles are, which the 18 clearances alone do not say; what to do about them is still learned.
# It trains on case=mix (Case 1, Case 2 and random circles in equal parts: random circles rarely come as close to a
# collision as the paper's cases) with a sharper tracking term (track_scale 2 cm: at 5 cm, exp(-e / 0.05) pays
# 0.82 of its maximum at a 1 cm error, and a first run tracked random circles at 15-27 mm).
RESIDUAL_CIRCLE_CLEARANCE="$RESIDUAL_CIRCLE --residual-observation clearance"
CIRCLE_MIX="case=mix hydro_randomization=0.3"
# The clearance-feature residual confined to the null space of both hand positions (--residual-space nullspace,
# uvdms_gym.residual.NullspaceProjection): to first order it cannot move the hands, so exploring it leaves the
# tracking to mpc; a hand-written field in that space kept 9-10 of 10 random circles contact-free (README).
RESIDUAL_CIRCLE_NULLSPACE="$RESIDUAL_CIRCLE_CLEARANCE --residual-space nullspace"
RESIDUAL_TRANSPORT="--residual mpc --residual-scale 0.3 --hyperparams action_scale=1.0"
# DAgger (agents/algos/dagger.py): the same residual over plain `mpc` (scale 0.5, clearance features), fitted to CAMPC's
# correction of mpc at every state the learner visits; CAMPC labels the training states and is not part of the
# agent (at evaluation: mpc + the network, no collision rows). Trained on case=mix, where the paper cases give
# the near-collision states that random circles rarely reach; the reward is not used for learning. The teacher
# is CAMPC with both collision thresholds 2 cm farther out (teacher_margin=0.02): imitating the registered CAMPC,
# a first run dipped 0.2-0.8 mm below d1 = 5 cm in 4 of 12 episodes, and with a 1 cm margin one seed of three still
# crossed d1 by 0.4 mm in Case 1, where that teacher (clipped to the residual) keeps 60.5 mm and with 2 cm 73.2 mm
# (README, "Learned entries").
RESIDUAL_DAGGER="--residual mpc --residual-scale 0.5 --residual-observation clearance --hyperparams teacher=campc teacher_margin=0.02"
# The obstacle task (uvdms/TransportObstacles-v1, moving obstacles and a random current): the same DAgger residual
# over plain `mpc`, fitted to CAMPC with its outer-obstacle rows (baselines/controllers.py: in an environment with
# obstacles the CAMPC baselines add them); the network sees the obstacle slots of the observation.
OBSTACLES="obstacles=random current=random"
RESIDUAL_DAGGER_OBSTACLES="--residual mpc --residual-scale 0.5 --hyperparams teacher=campc"
# Distilled controllers (docs/LEARNED_CONTROLLERS.md): DAgger with no base (--residual none), the network outputs the
# whole command and acts alone at evaluation (no MPC, no QP). Circles: CAMPC with a 2 cm margin as the teacher, on
# case=mix. Transport: the shipped residual entry residual-mpc-sac-transport-v1 (seed 0) as the teacher, which
# reaches random goals where CAMPC reaches half of them (committed leaderboard: 1.00 against 0.50). The learning
# rate decays linearly to zero (a constant 1e-3 left the imitation loss at its noise floor in a 60k-step pilot).
DISTILLED="--residual none --hyperparams learning_rate=lin_1e-3"
DISTILLED_CIRCLE="$DISTILLED teacher=campc teacher_margin=0.02"
DISTILLED_TRANSPORT="$DISTILLED teacher=residual-mpc-sac-transport-v1/seed_0"
# The cooperative transport (uvdms/CooperativeTransport-v1, the friction grasp, docs/cooperative.md): the cooperative
# CAMPC as the teacher of all 20 values (18 velocities and the 2 grip commands); 60k steps (the student met its
# evaluation episodes from 10k in a pilot).
DISTILLED_COOP="$DISTILLED teacher=campc-coop"
# The obstacle task as a network alone (docs/LEARNED_CONTROLLERS.md): CAMPC with its outer-obstacle rows as the
# teacher, its inner thresholds 2 cm and its outer-obstacle thresholds 5 cm farther out (it evades earlier and wider:
# more visited states carry an evasion, and the student's lag has room), and the imitation loss's hard-example
# emphasis (the batch's hardest quarter counts twice: the evasions are rare, sharp labels). The observation's obstacle
# slots are the student's only view of the obstacles. Plain DAgger (margin 2 cm, no emphasis) met 0.55 / 0.45 of 20
# validation draws at 60k steps and 0.60 / 0.60 at 80k (seeds 0 / 1), its failures contacts.
DISTILLED_OBSTACLES="$DISTILLED teacher=campc teacher_margin=0.02 teacher_outer_margin=0.05 hard_fraction=0.25"
# The same network alone with the obstacle features (uvdms_gym.residual.ObstacleFeatures, obstacle_features=true):
# besides the raw observation it observes, for each obstacle slot, the nearest robot part's gap, the gap's rates and
# the action direction that opens it, which the kinematic model computes from the observation (no optimisation; the
# slots stay the policy's only view of the obstacles). The plain DAgger recipe: CAMPC with the 2 cm inner margin.
# Alone (no entry; 3 seeds stopped at 100k steps) it met 0.80 / 0.75 / 0.65 of 20 validation draws.
DISTILLED_OBSTACLE_FEATURES="$DISTILLED teacher=campc teacher_margin=0.02 obstacle_features=true"
# ... and the evasion term of the imitation loss (evasion_weight, agents/algos/dagger.py): the squared error along
# each obstacle's weighted opening direction, twice. With least squares alone the students tracked well and missed
# the evasions: in the failed validation episodes of the features alone (seed 0 at 80k steps) the student's command
# opened the nearest gap at -0.25 to +0.07 m/s in the last second before the contact, where CAMPC, asked at the same
# states, opened it at +0.1 to +0.4 m/s (docs/challenged.md).
# Two gradient steps per env step (gradient_steps=2; 0.9.0 trained with one): the same 250k visited states, twice the
# fitting. A pilot (seed 0) met 0.80 of 50 validation draws where the one-step seed 0 met 0.68 (docs/challenged.md).
# Tried and not taken (0.9.2, docs/challenged.md): the teacher's outer-obstacle thresholds 3 cm farther out
# (teacher_outer_margin=0.03) with 180k steps, three seeds at the same time: 0.84 and 0.77 on the two test sets.
# The tracking error magnified (tracking_features=true, uvdms_gym.residual.TrackingFeatures; 0.9.3): half the failures
# were precision failures, the object held 2-7 cm from the goal, an error the observation gives as 0.04-0.14. A pilot
# (seed 0) met 0.87 of 100 validation draws where 0.9.1's seed 0 met 0.82 (docs/challenged.md).
DISTILLED_OBSTACLE_EVASION="$DISTILLED_OBSTACLE_FEATURES evasion_weight=2.0 gradient_steps=2 tracking_features=true"
# More visited states in the hour (0.9.4): four worker environments in their own processes (--vec-env subproc), 450k
# steps where 0.9.3 trained 250k with two environments in the trainer's process; the aggregated data set keeps every
# one of them (buffer_size), an evaluation every 20k steps. Fewer training episodes fit held-out episodes worse
# (scripts/dagger_heldout.py). A pilot (seed 0, 49.5 min) met 0.91 of 100 validation draws where 0.9.3's seed 0 met
# 0.87; the three seeds (49.5, 45.4 and 43.0 min, each alone) met 0.96 and 0.90 of the two test sets, 0.9.3's 0.91
# and 0.84 (docs/challenged.md).
DISTILLED_OBSTACLE_EVASION="$DISTILLED_OBSTACLE_EVASION buffer_size=450000 eval_freq=20000 --n-envs 4 --vec-env subproc"
# Under sensing and actuation realism (docs/realism.md), levels 2 and 3: a policy with memory distilled from the
# privileged CAMPC (the true state, the delay predicted; it labels the training states only). The student sees what
# the vehicle measures: the navigation filter's estimate (the vehicle's software, as campc uses it), its last 4
# observations and its own last 4 commands (under the 0.08-0.12 s action delay and the rotor lag, the commands still
# on their way); 0.16 s of history covers the level-3 delay and the rotor lag. One policy for both levels: its two
# training envs run level 2 and level 3 (env_variants). Without memory (the raw measured observation, the same
# teacher) a 30k-step pilot tracked random circles at 151 mm (level 2, 2 evaluation episodes).
MEMORY_REALISM="$DISTILLED teacher=campc-privileged navigation_filter=true frame_stack=4 action_history=4"
MEMORY_REALISM="$MEMORY_REALISM env_variants=[{\"realism\":2},{\"realism\":3}]"
# Fine-tuning a distilled controller with RL (agents/algos/td3_prior.py, prior_policy): TD3-prior starts its actor at
# the distilled network of the same seed ({seed} below) and holds it near that network's action instead of zero,
# on the v1 reward (default track_scale 5 cm). The actor waits 10k steps while the critic learns (a critic that has
# not seen the prior's returns would pull it anywhere); exploration noise 0.05 of the command range; prior_coef 10
# (TD3+BC's 0.4 let the actor leave the prior: every evaluation episode in contact after 10k actor updates).
# Pure RL, no teacher (docs/LEARNED_CONTROLLERS.md): PPO with the configuration `uvdms tune` found on the circles
# (train_configs/tuned/ppo_end_to_end.yml, its search record beside it), the same settings on transport.
PURE_RL="--config train_configs/tuned/ppo_end_to_end.yml"
# Pure RL over the full action range (docs/LEARNED_CONTROLLERS.md, "What holds the circle precision"): the
# earlier end-to-end entries trained with action_scale 0.3, below what tracking needs (CAMPC commands more than 0.3
# of zeta_max on some axis in 28 % of the circles' tracking steps, benchmarks/command_range.py). PPO-Lagrangian
# with no cap and a smaller initial log-std (train_configs/variants/ppo_lagrangian_full_range.yml); the circles
# also get the narrow tracking term (precision_weight, a v1 keyword off by default).
FULL_RANGE="--vec-env rollout --config train_configs/variants/ppo_lagrangian_full_range.yml"
PRECISION="precision_weight=1.0 precision_scale=0.03"
FINETUNE_CIRCLE="--hyperparams prior_policy=trained_agents/distilled-dagger-campc-circle-v1/seed_{seed} prior_coef=10.0 action_init_scale=null learning_starts=0 actor_warmup_steps=10000 noise_std=0.05"

# entry | algo | env id | env kwargs | extra training arguments ({seed}: the run's seed) | budget (env steps)
ENTRIES=(
  "sac-circle-v1|sac|uvdms/CircleTrack-v1|$CIRCLE $E2E||150000"
  "sac-transport-v1|sac|uvdms/Transport-v1|$TRANSPORT $E2E||150000"
  "residual-mpc-td3prior-circle-v1|td3_prior|uvdms/CircleTrack-v1|$CIRCLE $RESIDUAL_CIRCLE_KWARGS|$RESIDUAL_CIRCLE|150000"
  "residual-mpc-td3prior-clearance-circle-v1|td3_prior|uvdms/CircleTrack-v1|$CIRCLE_MIX $RESIDUAL_CIRCLE_KWARGS track_scale=0.02|$RESIDUAL_CIRCLE_CLEARANCE|150000"
  "residual-mpc-td3prior-nullspace-circle-v1|td3_prior|uvdms/CircleTrack-v1|$CIRCLE $RESIDUAL_CIRCLE_KWARGS|$RESIDUAL_CIRCLE_NULLSPACE|150000"
  "residual-mpc-dagger-campc-circle-v1|dagger|uvdms/CircleTrack-v1|$CIRCLE_MIX|$RESIDUAL_DAGGER|100000"
  "residual-mpc-dagger-campc-obstacles-v1|dagger|uvdms/TransportObstacles-v1|$OBSTACLES|$RESIDUAL_DAGGER_OBSTACLES|150000"
  "residual-mpc-sac-transport-v1|sac|uvdms/Transport-v1|$TRANSPORT|$RESIDUAL_TRANSPORT|150000"
  "distilled-dagger-campc-circle-v1|dagger|uvdms/CircleTrack-v1|$CIRCLE_MIX|$DISTILLED_CIRCLE|150000"
  "distilled-dagger-residual-transport-v1|dagger|uvdms/Transport-v1|$TRANSPORT|$DISTILLED_TRANSPORT|150000"
  "distilled-dagger-coop-transport-v1|dagger|uvdms/CooperativeTransport-v1|$TRANSPORT|$DISTILLED_COOP|60000"
  "distilled-dagger-campc-obstacles-v1|dagger|uvdms/TransportObstacles-v1|$OBSTACLES|$DISTILLED_OBSTACLES|120000"
  "distilled-evasion-dagger-campc-obstacles-v1|dagger|uvdms/TransportObstacles-v1|$OBSTACLES|$DISTILLED_OBSTACLE_EVASION|450000"
  "memory-dagger-privileged-circle-realism-v1|dagger|uvdms/CircleTrack-v1|$CIRCLE|$MEMORY_REALISM|60000"
  "memory-dagger-privileged-transport-realism-v1|dagger|uvdms/Transport-v1|$TRANSPORT|$MEMORY_REALISM|60000"
  "finetuned-td3prior-distilled-circle-v1|td3_prior|uvdms/CircleTrack-v1|$CIRCLE_MIX|$FINETUNE_CIRCLE|40000"
  "ppo-circle-v1|ppo|uvdms/CircleTrack-v1|$CIRCLE $E2E|$PURE_RL|300000"
  "ppo-transport-v1|ppo|uvdms/Transport-v1|$TRANSPORT $E2E|$PURE_RL|300000"
  "ppo-lagrangian-circle-v1|ppo_lagrangian|uvdms/CircleTrack-v1|$CIRCLE $E2E|$PPO_LAGRANGIAN|1000000"
  "ppo-lagrangian-transport-v1|ppo_lagrangian|uvdms/Transport-v1|$TRANSPORT $E2E|$PPO_LAGRANGIAN|1000000"
  "ppo-lagrangian-fullrange-circle-v1|ppo_lagrangian|uvdms/CircleTrack-v1|$CIRCLE $E2E $PRECISION|$FULL_RANGE|1200000"
  "ppo-lagrangian-fullrange-transport-v1|ppo_lagrangian|uvdms/Transport-v1|$TRANSPORT $E2E|$FULL_RANGE|1200000"
)

lookup() {
  local spec
  for spec in "${ENTRIES[@]}"; do
    if [[ "${spec%%|*}" == "$1" ]]; then
      echo "$spec"
      return 0
    fi
  done
  echo "unknown entry '$1' (scripts/train_v1_entries.sh list)" >&2
  return 2
}

run_dir() {  # the run directory of seed $3 of algo $2 under $1 (uvdms train --out $1)
  local dirs=("$1"/*/"$2_$3")
  [[ -d "${dirs[0]}" ]] && echo "${dirs[0]}"
}

train_one() {
  local entry=$1 algo=$2 env=$3 kwargs=$4 extra=${5//\{seed\}/$7} budget=$6 seed=$7 dir status
  mkdir -p "$OUT/logs"
  dir=$(run_dir "$OUT/$entry" "$algo" "$seed" || true)
  if [[ -n "$dir" ]]; then
    status=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["segments"][-1]["status"])' "$dir/meta.json")
    if [[ "$status" == completed ]]; then
      echo "$entry seed $seed: finished ($dir)"
      return 0
    fi
    echo "$entry seed $seed: resuming $dir ($status)"
    # shellcheck disable=SC2086
    "$UVDMS" train --resume "$dir" --no-progress >> "$OUT/logs/$entry-seed$seed.log" 2>&1
    return 0
  fi
  echo "$entry seed $seed: training $budget steps"
  # shellcheck disable=SC2086
  "$UVDMS" train --algo "$algo" --env "$env" --env-kwargs $kwargs $extra --seed "$seed" \
    --total-timesteps "$budget" --out "$OUT/$entry" --no-progress >> "$OUT/logs/$entry-seed$seed.log" 2>&1
}

export_entry() {
  local entry=$1 algo=$2 seed dir
  shift 2
  for seed in "$@"; do
    dir=$(run_dir "$OUT/$entry" "$algo" "$seed" || true)
    if [[ -z "$dir" ]]; then
      echo "$entry seed $seed: no run in $OUT/$entry, not exported" >&2
      continue
    fi
    rm -rf "$AGENTS/$entry/seed_$seed"
    mkdir -p "$AGENTS/$entry"
    "$UVDMS" export-agent "$dir" "$AGENTS/$entry/seed_$seed" --trust
  done
}

command=${1:-list}
case "$command" in
  list)
    printf '%s\n' "${ENTRIES[@]}" | column -t -s '|' ;;
  train | export)
    [[ $# -ge 2 ]] || { echo "usage: $0 $command ENTRY [SEED ...]" >&2; exit 2; }
    spec=$(lookup "$2")
    IFS='|' read -r entry algo env kwargs extra budget <<< "$spec"
    shift 2
    seeds=("$@")
    [[ ${#seeds[@]} -gt 0 ]] || seeds=(0 1 2)
    if [[ "$command" == train ]]; then
      for seed in "${seeds[@]}"; do
        train_one "$entry" "$algo" "$env" "$kwargs" "$extra" "$budget" "$seed"
      done
    fi
    export_entry "$entry" "$algo" "${seeds[@]}" ;;
  *)
    echo "usage: $0 list | train ENTRY [SEED ...] | export ENTRY [SEED ...]" >&2
    exit 2 ;;
esac
