#!/usr/bin/env bash
# Checks the rapier fork (vendor/rapier3d/PATCHES.md) against rapier 0.36.1 as published:
# the release CLI (no Rerun) built with the fork and with the published crate in double
# precision (cargo's copy of rapier3d 0.36.1 with its `f64` feature and parry3d-f64, the
# fork's change 4 and what the published rapier3d-f64 is), then every treadmill scenario
# and the in-air leg simulated by both (JSON over 20 s without its wall-clock
# `real_time_factor`, CSV over 10 s) and compared byte for byte. About 5 min warm.
#
#     bash tools/rapier-fork-check.sh
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

build() { # DIR OUT: the release CLI of the tree DIR, copied to OUT
  (cd "$1" && cargo build --release --no-default-features --bin pma-exo --quiet)
  cp "$CARGO_TARGET_DIR/release/pma-exo" "$2"
}
# The published rapier: cargo's copy of the crate, switched to f64 as the fork is.
published="$(ls -d "${CARGO_HOME:-$HOME/.cargo}"/registry/src/*/rapier3d-0.36.1 | head -n1)"
[ -d "$published" ] || { echo "no rapier3d-0.36.1 in cargo's registry: cargo fetch first" >&2; exit 1; }
cp -a "$published" "$work/rapier3d-published"
python3 - "$work/rapier3d-published/Cargo.toml" <<'PY'
import sys
p = sys.argv[1]
text = open(p).read()
edits = [
    ('"dim3",\n    "f32",', '"dim3",\n    "f64",'),
    ("\nf32 = []\n", "\nf32 = []\nf64 = []\n"),
    ("[dependencies.parry3d]", "[dependencies.parry3d-f64]"),
    ('"parry3d/', '"parry3d-f64/'),
]
for old, new in edits:
    if old not in text:
        sys.exit(f"rapier-fork-check.sh: the published Cargo.toml has no {old!r}")
    text = text.replace(old, new)
open(p, "w").write(text)
PY
# This tree with its [patch.crates-io] pointing at the published copy instead of the fork.
mkdir "$work/upstream"
(cd "$root" && git ls-files -z | xargs -0 cp -a --parents -t "$work/upstream")
python3 - "$work/upstream/Cargo.toml" "$work/rapier3d-published" <<'PY'
import sys
p, published = sys.argv[1], sys.argv[2]
text = open(p).read()
old = 'rapier3d = { path = "vendor/rapier3d" }'
if old not in text:
    sys.exit(f"rapier-fork-check.sh: Cargo.toml has no {old!r}")
open(p, "w").write(text.replace(old, f'rapier3d = {{ path = "{published}" }}'))
PY
build "$work/upstream" "$work/pma-exo-upstream"
build "$root" "$work/pma-exo-fork"

strip_clock() {
  python3 -c 'import json, sys; d = json.load(sys.stdin); d.pop("real_time_factor", None); print(json.dumps(d, sort_keys=True))'
}
status=0
for s in gait_treadmill gait_treadmill_spastic gait_treadmill_unsupported gait_treadmill_one_leg gait_training; do
  for v in upstream fork; do
    # The same file name for both: the CSV's first line quotes the command.
    mkdir -p "$work/out-$v"
    "$work/pma-exo-$v" simulate "$s" --duration 20 --json | strip_clock >"$work/out-$v/$s.json"
    (cd "$work/out-$v" && "$work/pma-exo-$v" simulate "$s" --duration 10 --csv "$s.csv" >/dev/null)
  done
  for ext in json csv; do
    if cmp -s "$work/out-upstream/$s.$ext" "$work/out-fork/$s.$ext"; then
      echo "$s $ext: identical"
    else
      echo "$s $ext: DIFFERENT"
      status=1
    fi
  done
done
exit $status
