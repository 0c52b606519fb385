#!/usr/bin/env bash
# RESULTS.md, "Layouts never seen": train on 16 and on 256 layouts of `toolbox` and on a
# fresh layout every episode (`all`) (three arms, 10 seeds, 2,000,896 env steps each),
# then play every run's final policy on 500 held-out layouts and on its training layouts
# (all 16 or 256; for `all`, the first 256 seeds of its training range), greedy and
# sampled (the actions drawn from the policy, as in training), and gather the
# rows into docs/results/layouts-evals.csv and the experiments' summaries into
# docs/results/layouts-<N>-summary.json (what scripts/layouts_tables.py reads).
#
# LAYOUTS picks the settings to run (default "16 256 all"); the rows of the settings not
# run are kept as they are in docs/results/layouts-evals.csv. PARALLEL runs that many
# runs at a time (default 1; the results are the same either way).
# Resumable: a finished run is kept, an evaluation already in a run's eval.csv is not
# made again.
set -euo pipefail
cd "$(dirname "$0")/.."
FULCRUM=${FULCRUM:-target/release/fulcrum}
OUT=${OUT:-experiments/layouts}
LAYOUTS=${LAYOUTS:-16 256 all}
PARALLEL=${PARALLEL:-1}
CSV=docs/results/layouts-evals.csv
for n in $LAYOUTS; do
  "$FULCRUM" experiment toolbox --seeds 10 --steps 2000896 \
    --arms baseline,horizon-potential,additive --parallel "$PARALLEL" --out "$OUT/$n" -- --layouts "$n"
  case $n in all) train=256 ;; *) train=$(( n < 256 ? n : 256 )) ;; esac
  for run in "$OUT/$n"/runs/*/seed-*; do
    for which in test:500 "train:$train"; do
      for mode in greedy sample; do
        if ! grep -q ",$which,$mode," "$run/eval.csv" 2>/dev/null; then
          "$FULCRUM" eval "$run" --layouts "$which" "--$mode" > /dev/null
        fi
      done
    done
  done
  cp "$OUT/$n/summary.json" "docs/results/layouts-$n-summary.json"
done
first=${LAYOUTS%% *}
{
  # eval.csv's own header, behind the three columns this file adds.
  echo "layouts_trained,arm,train_seed,$(head -1 "$(ls "$OUT/$first"/runs/*/seed-*/eval.csv | head -1)")"
  if [ -f "$CSV" ]; then
    # The committed rows of the settings not run now.
    tail -n +2 "$CSV" | while IFS= read -r row; do
      case " $LAYOUTS " in *" ${row%%,*} "*) ;; *) echo "$row" ;; esac
    done
  fi
  for n in $LAYOUTS; do
    for run in "$OUT/$n"/runs/*/seed-*; do
      arm=$(basename "$(dirname "$run")")
      seed=${run##*seed-}
      grep -E ",(greedy|sample)," "$run/eval.csv" | sed "s/^/$n,$arm,$seed,/"
    done
  done
} > "$CSV.tmp"
mv "$CSV.tmp" "$CSV"
echo "wrote $CSV"
