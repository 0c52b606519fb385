#!/usr/bin/env bash
# Regenerates every number and picture of RESULTS.md:
#   scripts/results.sh            the four experiments (10 seeds x 2 arms each), then pictures
#   scripts/results.sh pictures   only the matrices, landscapes and traces, and copies of
#                                 the curves of experiments already run
# Experiments go to experiments/<world> (resumable: run it again after an interruption);
# the committed pictures go to docs/results/.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
f=target/release/fulcrum
out=docs/results
mkdir -p "$out"

if [[ "${1:-}" != pictures ]]; then
  $f experiment exp1-tree --seeds 10 --steps 2097152 --out experiments/exp1-tree
  $f experiment exp1-wall --seeds 10 --steps 2097152 --out experiments/exp1-wall
  $f experiment exp2 --seeds 10 --steps 3145728 --out experiments/exp2
  $f experiment exp3 --seeds 10 --steps 3145728 --out experiments/exp3
fi
for w in exp1-tree exp1-wall exp2 exp3; do
  if [[ -f experiments/$w/summary.md ]]; then
    cp experiments/$w/plots/success.png "$out/$w-success.png"
    cp experiments/$w/plots/return.png "$out/$w-return.png"
    cp experiments/$w/summary.md "$out/$w-summary.md"
  fi
done

# Tables II and III, and exp3's matrix.
$f empowerment matrix exp1-tree --joint tree+wall --png "$out/exp1-tree-matrix.png" > "$out/exp1-tree-matrix.txt"
$f empowerment matrix exp2 --joint boulder+door --png "$out/exp2-matrix.png" > "$out/exp2-matrix.txt"
$f empowerment matrix exp3 --joint door+boulder --png "$out/exp3-matrix.png" > "$out/exp3-matrix.txt"
# Figs. 2 and 3: axe -> tree, h = 8 without the axe, h = 3 with it.
$f empowerment landscape exp1-tree --tool axe --objects tree --horizon 8 --png "$out/fig2-exp1-tree-axe-h8.png" > /dev/null
$f empowerment landscape exp1-tree --tool axe --objects tree --horizon 3 --holding axe --png "$out/fig3-exp1-tree-axe-h3-held.png" > /dev/null
# Fig. 6: wand -> boulder+door, h = 6, wand held.
$f empowerment landscape exp2 --tool wand --objects boulder,door --horizon 6 --holding wand --png "$out/fig6-exp2-wand-h6-held.png" > /dev/null
# Figs. 9 and 10: axe -> boulder, h = 10 without the axe (the world file's horizon; at the
# paper's h = 7 every value on this map is 0), h = 5 with it.
$f empowerment landscape exp3 --tool axe --objects boulder --horizon 10 --png "$out/fig9-exp3-axe-boulder-h10.png" > /dev/null
$f empowerment landscape exp3 --tool axe --objects boulder --horizon 5 --holding axe --png "$out/fig10-exp3-axe-boulder-h5-held.png" > /dev/null
# Fig. 12: the door's empowerment along a key episode (open, close, open, step in) and an
# axe episode (destroy).
$f empowerment trace exp3 --tool key --objects door --horizon 3 \
  --actions N,N,E,E,E,E,S,apply,key,E,apply,key,E,apply,key,E,E --png "$out/fig12-exp3-key-door.png" > /dev/null
$f empowerment trace exp3 --tool axe --objects door --horizon 3 \
  --actions S,E,E,E,E,N,N,apply,axe,E,E --png "$out/fig12-exp3-axe-door.png" > /dev/null
echo "pictures in $out"
