#!/usr/bin/env bash
# RESULTS.md "How far learned estimators are from the truth", its second half: PPO on
# the estimators' E against PPO on exact E (horizon-potential, default beta, 10 seeds).
#   scripts/estimators_ppo.sh [WORLD [STEPS]]     (default exp1-tree 499712; resumable)
# For every horizon h = 1..H the form sums (H = the larger of the world's two), a
# dataset of every state (32 uniform sequences a state, seed 0) and both reference
# estimators trained on it (examples/python/learned_empowerment.py, 1500 steps, seed 0);
# their estimates joined per estimator are what `train --empowerment-from` serves. The
# experiments' summaries are copied to docs/results/estimators-ppo-<world>-<arm>.json and
# scripts/estimators_ppo_table.py compares them.
set -euo pipefail
cd "$(dirname "$0")/.."
world=${1:-exp1-tree}
steps=${2:-499712}
f=${FULCRUM:-target/release/fulcrum}
py=${PYTHON:-target/py-venv/bin/python}
out=experiments/estimators/ppo/$world
mkdir -p "$out"
top=$($f world show "$world" --json | $py -c 'import json,sys; e=json.load(sys.stdin)["empowerment"]; print(max(e["horizon_unequipped"], e["horizon_equipped"]))')
for est in variational infonce; do
  joined=$out/$est.csv
  if [[ -f $joined ]]; then continue; fi
  for h in $(seq 1 "$top"); do
    data=$out/h$h.npz
    [[ -f $data ]] || $f empowerment dataset "$world" --horizon "$h" --states all --sequences 32 --seed 0 --out "$data" > /dev/null
    part=$out/h$h-$est.csv
    [[ -f $part ]] || $py examples/python/learned_empowerment.py "$data" --estimator "$est" --steps 1500 --log-every 0 --out "$part"
  done
  # One header, then every horizon's rows.
  { head -n 1 "$out/h1-$est.csv"; for h in $(seq 1 "$top"); do tail -n +2 "$out/h$h-$est.csv"; done; } > "$joined.tmp"
  mv "$joined.tmp" "$joined"
done
$f experiment "$world" --seeds 10 --steps "$steps" --arms baseline,horizon-potential --out "$out/exact"
for est in variational infonce; do
  $f experiment "$world" --seeds 10 --steps "$steps" --arms horizon-potential --out "$out/$est" -- --empowerment-from "$out/$est.csv"
done
for arm in exact variational infonce; do
  cp "$out/$arm/summary.json" "docs/results/estimators-ppo-$world-$arm.json"
done
