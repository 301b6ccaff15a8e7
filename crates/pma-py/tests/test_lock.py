"""The wheel is built from crates/pma-py/Cargo.lock, the CLI from the root Cargo.lock: every
crate both use must be at the same version in both, or the figures could differ."""
import re

from conftest import REPO

PACKAGE = re.compile(r'\[\[package\]\]\nname = "([^"]+)"\nversion = "([^"]+)"')


def versions(lock):
    found = {}
    for name, version in PACKAGE.findall(lock.read_text()):
        found.setdefault(name, set()).add(version)
    return found


def test_the_shared_crates_are_locked_at_the_same_versions():
    root = versions(REPO / "Cargo.lock")
    ours = versions(REPO / "crates" / "pma-py" / "Cargo.lock")
    shared = sorted(set(root) & set(ours))
    assert "rapier3d" in shared and "nalgebra" in shared
    differ = {n: (sorted(ours[n]), sorted(root[n])) for n in shared if not ours[n] <= root[n]}
    assert not differ, f"crates/pma-py/Cargo.lock differs from Cargo.lock (copy the root's versions): {differ}"
