#!/usr/bin/env bash
# Builds the release CLI (no Rerun) on rapier in double precision: this tree copied, its
# rapier fork (vendor/rapier3d) switched from f32 to f64 (parry3d-f64 for parry3d; the
# source is the same, rapier selects the precision by feature) and built in its own target
# directory. Prints the binary's path. For docs/convergence.md "The in-air figure in double
# precision": the same runs on both builds, e.g.
#
#     bin=$(bash tools/rapier-f64.sh)
#     python3 tools/perturbed_leg.py --bin "$bin" --substeps 8,32,64
#
# About 4 min cold (target: $PMA_F64_TARGET_DIR, default ~/.cache/pma-exo-f64).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
tree="${PMA_F64_TREE:-$HOME/.cache/pma-exo-f64-tree}"
export CARGO_TARGET_DIR="${PMA_F64_TARGET_DIR:-$HOME/.cache/pma-exo-f64}"
rm -rf "$tree"
mkdir -p "$tree"
(cd "$root" && git ls-files -z | xargs -0 cp -a --parents -t "$tree")
python3 - "$tree/vendor/rapier3d/Cargo.toml" <<'PY'
import sys
p = sys.argv[1]
text = open(p).read()
edits = [
    ('default = [\n    "dim3",\n    "f32",', 'default = [\n    "dim3",\n    "f64",'),
    ('required-features = [\n    "dim3",\n    "f32",', 'required-features = [\n    "dim3",\n    "f64",'),
    ("\nf32 = []\n", "\nf32 = []\nf64 = []\n"),
    ("[dependencies.parry3d]", "[dependencies.parry3d-f64]"),
    ('"parry3d/', '"parry3d-f64/'),
]
for old, new in edits:
    if old not in text:
        sys.exit(f"rapier-f64.sh: vendor/rapier3d/Cargo.toml no longer has {old!r}")
    text = text.replace(old, new)
open(p, "w").write(text)
PY
(cd "$tree" && cargo build --release --no-default-features --bin pma-exo --quiet >&2)
echo "$CARGO_TARGET_DIR/release/pma-exo"
