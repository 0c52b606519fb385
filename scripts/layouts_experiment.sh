#!/usr/bin/env bash
# RESULTS.md, "Layouts never seen": train on 16 and on 256 layouts of `toolbox` (three
# arms, 10 seeds, 2,000,896 env steps each), then play every run's final policy on 500
# held-out layouts and on its training layouts (at most 256), and gather the rows into
# docs/results/layouts-evals.csv and the experiments' summaries into
# docs/results/layouts-<N>-summary.json (what scripts/layouts_tables.py reads).
# Resumable: a finished run is kept, an evaluation already in a run's eval.csv is not
# made again.
set -euo pipefail
cd "$(dirname "$0")/.."
FULCRUM=${FULCRUM:-target/release/fulcrum}
OUT=${OUT:-experiments/layouts}
for n in 16 256; do
  "$FULCRUM" experiment toolbox --seeds 10 --steps 2000896 \
    --arms baseline,horizon-potential,additive --parallel 1 --out "$OUT/$n" -- --layouts "$n"
  train=$(( n < 256 ? n : 256 ))
  for run in "$OUT/$n"/runs/*/seed-*; do
    for which in test:500 "train:$train"; do
      if ! grep -q ",$which,greedy," "$run/eval.csv" 2>/dev/null; then
        "$FULCRUM" eval "$run" --layouts "$which" > /dev/null
      fi
    done
  done
  cp "$OUT/$n/summary.json" "docs/results/layouts-$n-summary.json"
done
{
  echo "layouts_trained,arm,train_seed,$(head -1 "$(ls "$OUT"/16/runs/*/seed-*/eval.csv | head -1)")"
  for n in 16 256; do
    for run in "$OUT/$n"/runs/*/seed-*; do
      arm=$(basename "$(dirname "$run")")
      seed=${run##*seed-}
      grep ",greedy," "$run/eval.csv" | sed "s/^/$n,$arm,$seed,/"
    done
  done
} > docs/results/layouts-evals.csv.tmp
mv docs/results/layouts-evals.csv.tmp docs/results/layouts-evals.csv
echo "wrote docs/results/layouts-evals.csv"
