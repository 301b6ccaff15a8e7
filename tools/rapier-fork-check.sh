#!/usr/bin/env bash
# Checks the rapier fork (vendor/rapier3d/PATCHES.md) against rapier 0.36.1 as published:
# the release CLI (no Rerun) built with the fork and without it, then every treadmill
# scenario and the in-air leg simulated by both (JSON over 20 s without its wall-clock
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
# The published rapier: this tree without its [patch.crates-io] section.
mkdir "$work/upstream"
(cd "$root" && git ls-files -z | xargs -0 cp -a --parents -t "$work/upstream")
python3 - "$work/upstream/Cargo.toml" <<'EOF'
import re, sys
p = sys.argv[1]
text = open(p).read()
open(p, "w").write(re.sub(r"(?ms)^\[patch\.crates-io\]\n.*?(?=^\[|\Z)", "", text))
EOF
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
