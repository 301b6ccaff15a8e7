#!/usr/bin/env bash
# The identification study of docs/commissioning.md: seven virtual muscles (plant files
# written here), each excited for 60 s on the virtual rig (`rig excite`) and identified
# three ways (`identify`); prints the table's rows. About 7 min (release, 2 cores).
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
# A valve without lag (issue 26: a lag on its bound derailed the fit), and the shipped
# default virtual rig as it is (plant `mismatch`, an ideal valve, 3 um of noise).
plant F 1.0 2.5 0.0 0.0 3e-6
cp "$root/crates/pma-rig/models/virtual.toml" G-rig.toml
# Each plant three ways: (1) the position alone and the weighed load; (2) the valve's
# pressure channel too; (3) the load not given: a second 60 s excitation with 1 kg added
# (`rig excite --added-mass-kg 1`), both logs identified together.
with_pressure() {
  sed 's/^charge_pump = \(.*\)$/charge_pump = \1\npressure = { subdevice = 0, channel = 1, range = 0, aref = "ground" }/' "$1-rig.toml" > "$1-rig-p.toml"
}
echo "| plant | truth: scales f0 f1 k0 k1 b0 b1, load, tau + theta, noise | protocol | lag (ms) | held-out fit | held-out RMS | noise found | cond | largest force-parameter error | load (kg) | s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for row in "A 2.5 0.9,1,1.2,1,1.2,1 20+0 20" "B 5.0 0.8,0.8,0.8,0.8,0.8,0.8 5+5 10" \
           "C 1.0 1.2,1.2,1.2,1.2,1.2,1.2 30+10 20" "D 2.0 1,1,1,1,1,1 10+0 0" \
           "E 3.5 0.85,0.9,1.1,0.9,1.15,0.9 15+8 15" "F 2.5 1,1,1,1,1,1 0+0 3" \
           "G 2.5 0.9,1,1.2,1,1.2,1 0+0 3"; do
  set -- $row
  with_pressure "$1"
  "$B" rig excite --config "$1-rig.toml" --out "$1.csv" --duration 60 > /dev/null
  "$B" rig excite --config "$1-rig-p.toml" --out "$1-p.csv" --duration 60 > /dev/null
  "$B" rig excite --config "$1-rig.toml" --out "$1-added.csv" --duration 60 --added-mass-kg 1 > /dev/null
  for protocol in weighed pressure added-mass; do
    case $protocol in
      weighed) args=("$1.csv" --load-kg "$2");;
      pressure) args=("$1-p.csv" --load-kg "$2");;
      added-mass) args=("$1.csv" "$1-added.csv");;
    esac
    start=$(date +%s.%N)
    "$B" identify "${args[@]}" --out "$1-$protocol-id.toml" --json --force > "$1-$protocol.json"
    secs=$(echo "$(date +%s.%N) - $start" | bc)
    python3 - "$1" "$2" "$3" "$4" "$5" "$secs" "$protocol" <<'PY'
import json, sys
name, load, scales, lag, noise, secs, protocol = sys.argv[1:]
d = json.load(open(f"{name}-{protocol}.json"))
est = {n: e["value"] for n, e in d["parameters"]}
f0, f1, k0, k1, b0, b1 = (float(v) for v in scales.split(","))
truth = {"f0_scale": f0, "f1_scale": f1, "k0_scale": k0, "k1_scale": k1,
         "b0_inflation_scale": b0, "b1_inflation_scale": b1,
         "b0_deflation_scale": b0, "b1_deflation_scale": b1}
err = {n: 100 * (est[n] - t) / t for n, t in truth.items()}
worst = max(err, key=lambda n: abs(err[n]))
print(f"| {name} | {scales}, {load} kg, {lag} ms, {noise} um | {protocol} | "
      f"{d['valve_time_constant_s']*1e3:.1f} + {d['valve_dead_time_s']*1e3:.1f} | "
      f"{d['fit_percent']:.2f} % | {d['rms_error_m']*1e6:.0f} um | {d['noise_rms_m']*1e6:.1f} um | "
      f"{d['condition_number']:.0f} | {err[worst]:+.1f} % ({worst.replace('_scale', '')}) | "
      f"{d['load_mass_kg']:.3f} ({100 * (d['load_mass_kg'] - float(load)) / float(load):+.1f} %) | {float(secs):.1f} |")
PY
  done
done
