//! The workspace's module structure: pma-leg's layers import only downwards (the layer
//! table is the chain of modules in `crates/pma-leg/src/lib.rs`'s docs), and no crate's
//! top-level modules import each other in a circle (what `../shared/tools/module_cycles.py`
//! reports, read the same way: `crate::` paths in non-test code).
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One top-level module's non-test source, concatenated over its files.
type Sources = BTreeMap<String, String>;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("readable source directory") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Code without its test module and its comments (a `crate::x` in a doc is no import).
fn non_test_code(text: &str) -> String {
    let code = text.split("\n#[cfg(test)]").next().unwrap_or_default();
    code.lines()
        .map(|l| l.split("//").next().unwrap_or_default())
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every top-level module of `src` (a file or a folder; `lib` and `main` left out) and its
/// code.
fn modules(src: &Path) -> Sources {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut out = Sources::new();
    for f in files {
        let rel = f.strip_prefix(src).expect("under src");
        let first = rel.components().next().expect("a component");
        let top = first.as_os_str().to_string_lossy();
        let top = top.strip_suffix(".rs").unwrap_or(&top).to_string();
        if top == "lib" || top == "main" {
            continue;
        }
        let text = std::fs::read_to_string(&f).expect("readable source");
        out.entry(top).or_default().push_str(&non_test_code(&text));
    }
    out
}

/// The modules `code` names with `crate::m` (also inside `use crate::{a, b::c}`).
fn referenced(code: &str) -> BTreeSet<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = BTreeSet::new();
    for (i, _) in code.match_indices("crate::") {
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let body = group.split('}').next().unwrap_or_default();
            out.extend(body.split(',').map(|p| ident(p.trim())));
        } else {
            out.insert(ident(rest));
        }
    }
    out.retain(|m| !m.is_empty());
    out
}

/// `a -> b` for every module `a` that names another module `b` of the same crate.
fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mods = modules(src);
    mods.iter()
        .map(|(m, code)| {
            let refs = referenced(code)
                .into_iter()
                .filter(|r| r != m && mods.contains_key(r))
                .collect();
            (m.clone(), refs)
        })
        .collect()
}

/// The circles of `g` (strongly connected components of more than one module), Tarjan.
fn circles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        for w in &s.g[v] {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if s.stack.contains(&w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = s.stack.pop() {
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

/// The layer table: the chain ``[`base`] -> [`gait`] -> ...`` in pma-leg's crate docs
/// (lib.rs), bottom first.
fn layer_table(lib_rs: &str) -> Vec<String> {
    let doc: String = lib_rs
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .collect::<Vec<_>>()
        .join(" ");
    let name = |piece: &str, last: bool| -> Option<String> {
        let links: Vec<&str> = piece.split("[`").skip(1).collect();
        let link = if last { links.last() } else { links.first() }?;
        Some(link.split('`').next()?.to_string())
    };
    let pieces: Vec<&str> = doc.split(" -> ").collect();
    let mut out: Vec<String> = pieces
        .first()
        .and_then(|p| name(p, true))
        .into_iter()
        .collect();
    out.extend(pieces.iter().skip(1).filter_map(|p| name(p, false)));
    out
}

/// Every `module -> layer it must not name` of `g` under `layers`, plus the modules the
/// table does not list.
fn upward_imports(g: &BTreeMap<String, BTreeSet<String>>, layers: &[String]) -> Vec<String> {
    let rank = |m: &str| layers.iter().position(|l| l == m);
    let mut out = Vec::new();
    for (m, refs) in g {
        let Some(own) = rank(m) else {
            out.push(format!("{m} is not in lib.rs's layer table"));
            continue;
        };
        for r in refs {
            if rank(r).is_some_and(|r_rank| r_rank > own) {
                out.push(format!("{m} imports {r}, a layer above it"));
            }
        }
    }
    out
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn pma_legs_layers_import_only_downwards() {
    let src = root().join("crates/pma-leg/src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("lib.rs");
    let layers = layer_table(&lib);
    assert!(layers.len() >= 8, "layer table: {layers:?}");
    let g = graph(&src);
    let bad = upward_imports(&g, &layers);
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    // A root re-export (`crate::Scenario`) would hide which layer a path reaches into.
    for (m, code) in modules(&src) {
        let hidden: Vec<_> = referenced(&code)
            .into_iter()
            .filter(|r| r.starts_with(|c: char| c.is_ascii_uppercase()))
            .collect();
        assert!(
            hidden.is_empty(),
            "{m} names {hidden:?} through the crate root"
        );
    }
}

#[test]
fn an_upward_import_is_found() {
    let layers = ["base", "gait", "scenario"].map(String::from);
    let code = "use crate::base::LegError;\nfn f(s: &crate::scenario::Scenario) {}\n";
    let mut g = BTreeMap::new();
    g.insert("gait".to_string(), referenced(&non_test_code(code)));
    g.get_mut("gait")
        .expect("gait")
        .retain(|r| layers.contains(r));
    assert_eq!(
        upward_imports(&g, &layers),
        ["gait imports scenario, a layer above it"]
    );
    // The same path in a test module or a comment is not an import.
    let tested =
        "// crate::scenario::x\n#[cfg(test)]\nmod tests { use crate::scenario::Scenario; }";
    assert!(referenced(&non_test_code(tested)).is_empty());
}

#[test]
fn no_crate_has_a_circle_of_modules() {
    let mut dirs = vec![root().join("src")];
    for entry in std::fs::read_dir(root().join("crates")).expect("crates/") {
        let src = entry.expect("entry").path().join("src");
        if src.is_dir() {
            dirs.push(src);
        }
    }
    let found: Vec<String> = dirs
        .iter()
        .flat_map(|d| {
            circles(&graph(d))
                .into_iter()
                .map(move |c| format!("{}: {}", d.display(), c.join(", ")))
        })
        .collect();
    assert!(found.is_empty(), "circles:\n{}", found.join("\n"));
}

#[test]
fn a_circle_is_found() {
    let mut g = BTreeMap::new();
    for (a, b) in [("a", "b"), ("b", "c"), ("c", "a"), ("d", "a")] {
        g.entry(a.to_string())
            .or_insert_with(BTreeSet::new)
            .insert(b.to_string());
        g.entry(b.to_string()).or_insert_with(BTreeSet::new);
    }
    assert_eq!(circles(&g), [["a", "b", "c"].map(String::from).to_vec()]);
}
