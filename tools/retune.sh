#!/usr/bin/env bash
# Regenerates every tuned gain file with the release binary (deterministic: same seeds,
# same results on any machine and thread count), then the compiled-in defaults.
#   models/gains/<controller>.toml, aprc-ndo-tuned.toml: unconstrained, seed 1;
#   models/gains/equal-activity/<budget>/<controller>.toml: best sine IAE of seeds 1-3
#   within the budget (models/gains/equal-activity/README.md).
# Usage: tools/retune.sh [path/to/pma-exo]   (about 4 min on 2 cores)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/pma-exo}
search=(--plant mismatch --population 25 --generations 60 --duration 20)
for c in psmc ndo-smc sta pid aprc-ndo; do
  out=models/gains/$c.toml
  [ "$c" = aprc-ndo ] && out=models/gains/aprc-ndo-tuned.toml
  "$bin" tune --controller "$c" "${search[@]}" --seed 1 --out "$out"
done
tmp=$(mktemp -d)
for budget in 1.5 3 6; do
  for c in aprc-ndo ndo-smc psmc sta pid; do
    best=""
    for seed in 1 2 3; do
      f=$tmp/$c-$budget-$seed.toml
      if "$bin" tune --controller "$c" "${search[@]}" --seed "$seed" --max-variation "$budget" --out "$f" 2>/dev/null; then
        iae=$(sed -n 's/.*sine IAE \([0-9.e+-]*\) m.*/\1/p' "$f")
        if [ -z "$best" ] || python3 -c "import sys; sys.exit(0 if $iae < $best_iae else 1)"; then
          best=$f; best_iae=$iae
        fi
      fi
    done
    [ -n "$best" ] || { echo "no seed met $budget bar/s for $c" >&2; exit 1; }
    { echo "# Equal-activity protocol (models/gains/equal-activity/README.md): best sine IAE of seeds 1-3 within $budget bar/s."; cat "$best"; } \
      > "models/gains/equal-activity/$budget/$c.toml"
  done
done
rm -rf "$tmp"
python3 tools/gen_tuned_gains.py
