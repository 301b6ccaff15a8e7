#!/usr/bin/env bash
# Regenerates every tuned gain file with the release binary (deterministic: same seeds,
# same results on any machine and thread count), then the compiled-in defaults.
#   crates/pma-control/models/gains/<controller>.toml, aprc-ndo-tuned.toml: unconstrained, seed 1;
#   crates/pma-studies/models/gains/equal-activity/<budget>/<controller>.toml: best sine IAE of seeds 1-3
#   within the budget (crates/pma-studies/models/gains/equal-activity/README.md).
# Every file is tuned into a staging directory first; the gain directories are only
# touched once the whole set succeeded, so an interrupted or failed retune leaves the shipped gains as
# they were.
# Usage: tools/retune.sh [path/to/pma-exo]   (about 4 min on 2 cores)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/pma-exo}
search=(--plant mismatch --population 25 --generations 60 --duration 20)
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/gains" "$stage/equal-activity"
for c in psmc ndo-smc sta pid aprc-ndo; do
  out=$stage/gains/$c.toml
  [ "$c" = aprc-ndo ] && out=$stage/gains/aprc-ndo-tuned.toml
  "$bin" tune --controller "$c" "${search[@]}" --seed 1 --out "$out"
done
for budget in 1.5 3 6; do
  mkdir -p "$stage/equal-activity/$budget"
  for c in aprc-ndo ndo-smc psmc sta pid; do
    best=""
    for seed in 1 2 3; do
      f=$stage/$c-$budget-$seed.toml
      if "$bin" tune --controller "$c" "${search[@]}" --seed "$seed" --max-variation "$budget" --out "$f" 2>/dev/null; then
        iae=$(sed -n 's/.*sine IAE \([0-9.e+-]*\) m.*/\1/p' "$f")
        if [ -z "$best" ] || python3 -c "import sys; sys.exit(0 if $iae < $best_iae else 1)"; then
          best=$f; best_iae=$iae
        fi
      fi
    done
    [ -n "$best" ] || { echo "no seed met $budget bar/s for $c" >&2; exit 1; }
    { echo "# Equal-activity protocol (crates/pma-studies/models/gains/equal-activity/README.md): best sine IAE of seeds 1-3 within $budget bar/s."; cat "$best"; } \
      > "$stage/equal-activity/$budget/$c.toml"
  done
done
# The whole set is there: move it in (each rename is atomic).
mv -f "$stage"/gains/*.toml crates/pma-control/models/gains/
for budget in 1.5 3 6; do
  mv -f "$stage/equal-activity/$budget"/*.toml "crates/pma-studies/models/gains/equal-activity/$budget/"
done
python3 tools/gen_tuned_gains.py
