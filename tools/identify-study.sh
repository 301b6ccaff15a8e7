#!/usr/bin/env bash
# The identification study of docs/commissioning.md: five virtual muscles (plant files
# written here), each excited for 60 s on the virtual rig (`rig excite`) and identified
# with its weighed load (`identify`); prints the table's rows. About 1 min (release).
# Usage: tools/identify-study.sh [PMA_EXO_BINARY]
set -euo pipefail
B=${1:-target/release/pma-exo}
B=$(realpath "$B")
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
# name scale load_kg tau_s theta_s noise_m f0 k0 b0 (f0, k0, b0 default to scale)
plant() {
  local name=$1 s=$2 load=$3 tau=$4 theta=$5 noise=$6 f0=${7:-$2} k0=${8:-$2} b0=${9:-$2}
  cat > "$name-plant.toml" <<EOP
name = "$name"
[nominal]
mass_kg = 2.0
[muscle]
f0_scale = $f0
f1_scale = $s
k0_scale = $k0
k1_scale = $s
b0_inflation_scale = $b0
b1_inflation_scale = $s
b0_deflation_scale = $b0
b1_deflation_scale = $s
[load]
mass_kg = $load
[valve]
pressure_max_pa = 6.0e5
time_constant_s = $tau
dead_time_s = $theta
[sensor]
range_min_m = -0.02
range_max_m = 0.150
resolution_bits = 16
noise_rms_m = 0.0
seed = 1
EOP
  sed "s/^plant = \"mismatch\"/plant = \"$name-plant.toml\"/; s/^sensor_noise_rms_m = .*/sensor_noise_rms_m = $noise/" \
    "$root/crates/pma-rig/models/virtual.toml" > "$name-rig.toml"
}
plant A 1.0 2.5 0.020 0.000 20e-6 0.9 1.2 1.2
plant B 0.8 5.0 0.005 0.005 10e-6
plant C 1.2 1.0 0.030 0.010 20e-6
plant D 1.0 2.0 0.010 0.000 0
plant E 0.9 3.5 0.015 0.008 15e-6 0.85 1.1 1.15
echo "| plant | truth: scales f0 f1 k0 k1 b0 b1, load, tau + theta, noise | lag (ms) | held-out fit | held-out RMS | residual RMS | cond | f0 f1 k0 k1 b0i b1i b0d b1d | s |"
echo "|---|---|---|---|---|---|---|---|---|"
for row in "A 2.5 0.9,1,1.2,1,1.2,1 20+0 20" "B 5.0 0.8,0.8,0.8,0.8,0.8,0.8 5+5 10" \
           "C 1.0 1.2,1.2,1.2,1.2,1.2,1.2 30+10 20" "D 2.0 1,1,1,1,1,1 10+0 0" \
           "E 3.5 0.85,0.9,1.1,0.9,1.15,0.9 15+8 15"; do
  set -- $row
  "$B" rig excite --config "$1-rig.toml" --out "$1.csv" --duration 60 > /dev/null
  start=$(date +%s.%N)
  "$B" identify "$1.csv" --load-kg "$2" --out "$1-id.toml" --json --force > "$1.json"
  secs=$(echo "$(date +%s.%N) - $start" | bc)
  python3 - "$1" "$2" "$3" "$4" "$5" "$secs" <<'PY'
import json, sys
name, load, scales, lag, noise, secs = sys.argv[1:]
d = json.load(open(f"{name}.json"))
p = [e["value"] for _, e in d["parameters"]]
print(f"| {name} | {scales}, {load} kg, {lag} ms, {noise} um | "
      f"{d['valve_time_constant_s']*1e3:.1f} + {d['valve_dead_time_s']*1e3:.1f} | "
      f"{d['fit_percent']:.2f} % | {d['rms_error_m']*1e6:.0f} um | {d['noise_rms_m']*1e6:.0f} um | "
      f"{d['condition_number']:.0f} | " + " ".join(f"{v:.3f}" for v in p[:8]) + f" | {float(secs):.1f} |")
PY
done
