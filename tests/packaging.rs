//! Every library crate packages on its own: a file it embeds (`include_str!`,
//! `include_bytes!`) lies inside the crate's own directory, so `cargo package` ships it.
//! CI also runs `cargo package --workspace --exclude pma-exo --no-verify` (manifests,
//! file lists); the full verification, which compiles each package alone, is
//! `cargo package --workspace --exclude pma-exo` (about 8 min cold here, mostly Rerun).
use std::path::{Component, Path, PathBuf};

/// Paths named by the include macros of one source file: the first string literal after
/// each macro (for `concat!`, its leading literal, a directory).
fn included_paths(source: &str) -> Vec<String> {
    let mut out = Vec::new();
    for mac in ["include_str!(", "include_bytes!("] {
        for (at, _) in source.match_indices(mac) {
            let rest = &source[at + mac.len()..];
            let Some(open) = rest.find('"') else { continue };
            let Some(len) = rest[open + 1..].find('"') else {
                continue;
            };
            out.push(rest[open + 1..open + 1 + len].to_owned());
        }
    }
    out
}

/// `base/rel` with `.` and `..` resolved lexically.
fn resolve(base: &Path, rel: &str) -> PathBuf {
    let mut p = PathBuf::new();
    for c in base.join(rel).components() {
        match c {
            Component::ParentDir => {
                p.pop();
            }
            Component::CurDir => {}
            other => p.push(other),
        }
    }
    p
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("read_dir").flatten() {
        let p = entry.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn every_embedded_file_lies_inside_its_crate() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut checked = 0;
    for krate in std::fs::read_dir(root.join("crates"))
        .expect("crates")
        .flatten()
    {
        let dir = resolve(&krate.path(), ".");
        let mut files = Vec::new();
        rust_files(&dir.join("src"), &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).expect("source");
            for rel in included_paths(&text) {
                let target = resolve(file.parent().expect("parent"), &rel);
                assert!(
                    target.starts_with(&dir),
                    "{} embeds {rel}, outside {}: `cargo package` would not ship it",
                    file.display(),
                    dir.display()
                );
                assert!(target.exists(), "{} embeds {rel}: missing", file.display());
                checked += 1;
            }
        }
    }
    // The URDF, muscles, scenarios, gait, gains, plants, rig configs and sweeps.
    assert!(checked >= 30, "only {checked} embedded files found");
}

#[test]
fn the_include_scanner_finds_what_it_should() {
    let src = "const A: &str = include_str!(\"../models/a.toml\");\n\
               const B: &[u8] = include_bytes!(concat!(\"../m/\", \"b\"));";
    assert_eq!(included_paths(src), ["../models/a.toml", "../m/"]);
    assert_eq!(
        resolve(Path::new("/w/crates/x/src"), "../models/a.toml"),
        Path::new("/w/crates/x/models/a.toml")
    );
}

/// Every file under `dir` (following symbolic links), canonicalised.
fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("read_dir").flatten() {
        let p = entry.path();
        if p.is_dir() {
            files_under(&p, out);
        } else {
            out.push(std::fs::canonicalize(&p).expect("a link that resolves"));
        }
    }
}

/// Issue 26: the top-level `models/` holds every file a user edits (each a link into the
/// crate that embeds it); a model file added to a crate and not linked there fails here.
#[test]
fn every_model_file_of_every_crate_is_found_under_the_top_level_models() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut linked = Vec::new();
    files_under(&root.join("models"), &mut linked);
    let mut missing = Vec::new();
    let mut checked = 0;
    for krate in std::fs::read_dir(root.join("crates"))
        .expect("crates")
        .flatten()
    {
        let models = krate.path().join("models");
        if !models.is_dir() {
            continue;
        }
        let mut files = Vec::new();
        files_under(&models, &mut files);
        for f in files {
            checked += 1;
            if !linked.contains(&f) {
                missing.push(f.display().to_string());
            }
        }
    }
    assert!(checked > 30, "only {checked} model files found");
    assert!(missing.is_empty(), "not under models/: {missing:?}");
}
