#!/usr/bin/env bash
# The Monte Carlo with robust gains of docs/commissioning.md (protocol fixed before the
# runs): APRC-NDO, PID and PSMC tuned robustly (p90 of the IAE) on 16 plants drawn from
# the `monte_carlo` sweep's ranges with seed 2019, at 3 and at 12 bar/s; then the 200
# plants of `monte_carlo` itself (seed 1) with the gains that were found. About 6 min
# (release, 2 cores). Usage: tools/monte-carlo-robust.sh [PMA_EXO_BINARY] [OUT_DIR]
set -euo pipefail
B=$(realpath "${1:-target/release/pma-exo}")
out=${2:-$(mktemp -d)}
mkdir -p "$out"
cd "$out"
gains=()
for budget in 3 12; do
  for c in aprc-ndo pid psmc; do
    if "$B" tune --controller "$c" --robust 16 --robust-from monte_carlo --objective p90 \
        --max-variation "$budget" --seed 2019 --out "$c-$budget.toml" --yes 2> "$c-$budget.log"; then
      gains+=("\"$c-$budget.toml\"")
    fi
    echo "$c at $budget bar/s: $(tail -1 "$c-$budget.log")"
  done
done
cat > robust.toml <<EOS
name = "monte_carlo_robust"
description = "the monte_carlo population with robustly tuned gains"
duration_s = 20.0

[[grid]]
controllers = ["aprc-ndo", "pid", "psmc"]
gains = [$(IFS=,; echo "${gains[*]}")]
references = ["sine", "chirp"]
[grid.plants.population]
size = 200
seed = 1
muscle_scale = [0.8, 1.2]
load_kg = [1.0, 5.0]
valve_lag_s = [0.0, 0.030]
noise_rms_m = [0.0, 20e-6]
EOS
"$B" sweep robust.toml --out sweep > /dev/null
cat sweep/summary.md
