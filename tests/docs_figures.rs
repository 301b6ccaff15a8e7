//! Every figure listed in `docs/figures.toml` is rerun from the command the docs show
//! beside it, and the docs must say what it gives now: a figure written by hand goes stale
//! at the next change, this test says which and what it should be. The fast figures run
//! here; the slow ones (long runs, commissioning) with
//! `cargo test --release --test docs_figures -- --ignored`.
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::process::Command;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    #[serde(default)]
    file: Vec<InputFile>,
    figure: Vec<Figure>,
    #[serde(default)]
    image: Vec<Image>,
}

/// An image of the docs: the command draws it at `drawn`; it must be the same bytes.
/// `PMA_BLESS=1` copies the drawn image over the doc's instead (regeneration).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Image {
    path: String,
    command: Vec<String>,
    drawn: String,
    /// The exit status the command must end with, where it is not a success.
    #[serde(default)]
    exit: Option<i32>,
    #[serde(default)]
    slow: bool,
}

/// An input the commands share: a repository file with replacements, written once.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InputFile {
    name: String,
    from: String,
    #[serde(default)]
    replace: Vec<[String; 2]>,
}

/// A figure: the command (`pma-exo` arguments; `{dir}` is the test's directory), and the
/// text the doc must contain, with `{json.path:.N}` (optionally `{path*1e3:.N}`) where the
/// command's JSON output goes.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Figure {
    doc: String,
    command: Vec<String>,
    #[serde(default)]
    text: Vec<String>,
    /// A markdown file the command writes (`{dir}`-relative paths allowed): every table
    /// row of it must be in the doc, as it is.
    #[serde(default)]
    rows_of: Option<String>,
    /// The exit status the command must end with, where it is not a success (`size`
    /// refusing a recommendation that does not hold in closed loop: 1).
    #[serde(default)]
    exit: Option<i32>,
    #[serde(default)]
    slow: bool,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn manifest() -> Manifest {
    let text = std::fs::read_to_string(root().join("docs/figures.toml")).expect("figures.toml");
    toml::from_str(&text).expect("docs/figures.toml")
}

fn work_dir(m: &Manifest, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pma-exo-docs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    for f in &m.file {
        let mut text = std::fs::read_to_string(root().join(&f.from)).expect("input");
        for [from, to] in &f.replace {
            assert!(text.contains(from.as_str()), "{}: no `{from}`", f.from);
            text = text.replace(from.as_str(), to);
        }
        std::fs::write(dir.join(&f.name), text).expect("write input");
    }
    dir
}

/// The JSON at a dotted path (`a.b.0.c`).
fn at<'a>(json: &'a serde_json::Value, path: &str) -> &'a serde_json::Value {
    let mut v = json;
    for key in path.split('.') {
        v = match key.parse::<usize>() {
            Ok(i) => &v[i],
            Err(_) => &v[key],
        };
    }
    v
}

/// The value at a dotted path (`a.b.0.c`), times an optional `*factor`.
fn value(json: &serde_json::Value, expr: &str) -> f64 {
    let (path, factor) = match expr.split_once('*') {
        Some((p, f)) => (p, f.parse::<f64>().expect("factor")),
        None => (expr, 1.0),
    };
    at(json, path)
        .as_f64()
        .unwrap_or_else(|| panic!("`{path}` is not a number in {json}"))
        * factor
}

/// `template` with every `{expr:.N}` replaced by the value, N decimals.
fn expand(template: &str, json: &serde_json::Value) -> String {
    let mut out = String::new();
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let close = rest[open..].find('}').expect("unclosed {") + open;
        let field = &rest[open + 1..close];
        match field.split_once(":.") {
            Some((expr, digits)) => {
                let digits: usize = digits.parse().expect("digits");
                out.push_str(&format!("{:.*}", digits, value(json, expr)));
            }
            // A string, as the command gave it (`{path}`).
            None => out.push_str(
                at(json, field)
                    .as_str()
                    .unwrap_or_else(|| panic!("`{field}` is not a string in {json}")),
            ),
        }
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    out
}

/// The data rows of the markdown tables in `text` (not the header nor the separator).
fn table_rows(text: &str) -> Vec<&str> {
    let lines: Vec<&str> = text.lines().collect();
    lines
        .iter()
        .enumerate()
        .filter(|(i, l)| {
            l.starts_with("| ")
                && !l.starts_with("|---")
                && !lines.get(i + 1).is_some_and(|n| n.starts_with("|---"))
        })
        .map(|(_, l)| *l)
        .collect()
}

/// The tables of `text`, each as its data rows (runs of consecutive `table_rows`).
fn table_groups(text: &str) -> Vec<Vec<String>> {
    let rows: std::collections::HashSet<&str> = table_rows(text).into_iter().collect();
    let mut groups: Vec<Vec<String>> = Vec::new();
    let mut current = Vec::new();
    for line in text.lines() {
        if rows.contains(line) {
            current.push(line.to_owned());
        } else if !current.is_empty() {
            groups.push(std::mem::take(&mut current));
        }
    }
    groups.extend((!current.is_empty()).then_some(current));
    groups
}

/// Where in `lines` (indentation aside: a table in a list item) `rows` stand together, in
/// order: the line of the first, for each place.
fn table_starts(lines: &[&str], rows: &[String]) -> Vec<usize> {
    (0..=lines.len().saturating_sub(rows.len()))
        .filter(|&j| {
            rows.iter()
                .enumerate()
                .all(|(i, r)| lines[j + i].trim_start() == r)
        })
        .collect()
}

/// A `rows_of` table whose rows are all in `doc` must stand there together as one table,
/// and a doc's tables in the manifest's order: `tools/figures.py --apply` replaces a stale
/// table by its rank among the doc's tables with the same labels, so a row found elsewhere
/// (another table's row with the same label) or a table out of order is where an apply
/// writes one table's numbers into another (three times up to stop 74).
fn misplaced_tables(doc: &str, text: &str, tables: &[(&Figure, Vec<String>)]) -> Vec<String> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut after = None;
    for (f, rows) in tables {
        if !rows.iter().all(|r| text.contains(r.as_str())) {
            continue; // stale rows, reported one by one
        }
        let command = f.command.join(" ");
        let starts = table_starts(&lines, rows);
        if starts.is_empty() {
            out.push(format!(
                "{doc}: the rows of one table of `pma-exo {command}` are in the doc but not \
                 together (a row in another table?), first `{}`",
                rows[0]
            ));
            continue;
        }
        match starts.iter().find(|&&j| after.is_none_or(|a| j > a)) {
            Some(&j) => after = Some(j),
            None => out.push(format!(
                "{doc}: the table of `pma-exo {command}` starting `{}` stands before the table \
                 the manifest lists ahead of it (docs/figures.toml lists a doc's figures in its \
                 order)",
                rows[0]
            )),
        }
    }
    out
}

fn run(command: &[String], dir: &Path, exit: Option<i32>) -> serde_json::Value {
    let args: Vec<String> = command
        .iter()
        .map(|a| a.replace("{dir}", &dir.display().to_string()))
        .collect();
    let out = Command::new(env!("CARGO_BIN_EXE_pma-exo"))
        .args(&args)
        .current_dir(dir)
        .output()
        .expect("run pma-exo");
    let expected = match exit {
        Some(code) => out.status.code() == Some(code),
        None => out.status.success() || out.status.code() == Some(3),
    };
    assert!(
        expected,
        "pma-exo {} (exit {:?}, expected {exit:?}): {}",
        args.join(" "),
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().last().unwrap_or_default();
    serde_json::from_str(line).unwrap_or(serde_json::Value::Null)
}

/// A command with the exit status it must end with.
type Job<'a> = (&'a [String], Option<i32>);

/// Runs each distinct command once (docs/img's table2.png and fig9.png come from one
/// `paper` run; two runs of it at a time would write the same files), on as many threads
/// as the machine has cores (the commands are single-threaded and write only under their
/// own names in `dir`, as `tools/figures.py -j N` runs them), and returns the JSON of each
/// of `jobs` in order.
fn run_all(jobs: &[Job], dir: &Path) -> Vec<serde_json::Value> {
    use rayon::prelude::*;
    let mut distinct: Vec<Job> = Vec::new();
    let slots: Vec<usize> = jobs
        .iter()
        .map(|job| {
            distinct.iter().position(|d| d == job).unwrap_or_else(|| {
                distinct.push(*job);
                distinct.len() - 1
            })
        })
        .collect();
    let jsons: Vec<serde_json::Value> = distinct
        .par_iter()
        .map(|(command, exit)| run(command, dir, *exit))
        .collect();
    slots.into_iter().map(|i| jsons[i].clone()).collect()
}

fn check(slow: bool) {
    let m = manifest();
    let dir = work_dir(&m, if slow { "slow" } else { "fast" });
    let mut stale = Vec::new();
    let mut checked = 0;
    let figures: Vec<&Figure> = m.figure.iter().filter(|f| f.slow == slow).collect();
    let images: Vec<&Image> = m.image.iter().filter(|i| i.slow == slow).collect();
    // The images' commands run with the figures', all in parallel: drawn last, one at a
    // time, they kept a core idle.
    let jobs: Vec<Job> = figures
        .iter()
        .map(|f| (f.command.as_slice(), f.exit))
        .chain(images.iter().map(|i| (i.command.as_slice(), i.exit)))
        .collect();
    let mut jsons = run_all(&jobs, &dir);
    jsons.truncate(figures.len());
    // Each doc's `rows_of` tables, in the manifest's order, for `misplaced_tables`.
    let mut placed: std::collections::BTreeMap<&str, Vec<(&Figure, Vec<String>)>> =
        Default::default();
    for (f, json) in figures.iter().zip(jsons) {
        let doc = std::fs::read_to_string(root().join(&f.doc)).expect("doc");
        let mut expected: Vec<String> = f.text.iter().map(|t| expand(t, &json)).collect();
        if let Some(path) = &f.rows_of {
            let path = path.replace("{dir}", &dir.display().to_string());
            let text = std::fs::read_to_string(&path).expect("the command's markdown");
            let groups = table_groups(&text);
            expected.extend(groups.iter().flatten().cloned());
            let tables = placed.entry(f.doc.as_str()).or_default();
            tables.extend(groups.into_iter().map(|rows| (*f, rows)));
        }
        for expected in expected {
            checked += 1;
            if !doc.contains(&expected) {
                stale.push(format!(
                    "{}: should say `{expected}` (`pma-exo {}`)",
                    f.doc,
                    f.command.join(" ")
                ));
            }
        }
    }
    for (doc, tables) in &placed {
        let text = std::fs::read_to_string(root().join(doc)).expect("doc");
        stale.extend(misplaced_tables(doc, &text, tables));
    }
    let write = std::env::var_os("PMA_BLESS").is_some();
    for image in images {
        let drawn = image.drawn.replace("{dir}", &dir.display().to_string());
        let new = std::fs::read(&drawn).expect("the drawn image");
        let path = root().join(&image.path);
        checked += 1;
        if write {
            std::fs::write(&path, &new).expect("write the image");
        } else if std::fs::read(&path).ok().as_deref() != Some(new.as_slice()) {
            stale.push(format!(
                "{}: differs from what `pma-exo {}` draws (PMA_BLESS=1 regenerates it)",
                image.path,
                image.command.join(" ")
            ));
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        stale.is_empty(),
        "{} of {checked} figures are stale:\n{}",
        stale.len(),
        stale.join("\n")
    );
}

#[test]
fn the_docs_say_what_their_commands_give() {
    check(false);
}

#[test]
#[ignore = "minutes: run with --release -- --ignored"]
fn the_docs_say_what_their_slow_commands_give() {
    check(true);
}

/// docs/convergence.md "rapier's floor" prints `pma_leg::tools::step_floor`'s rows (`cargo run
/// --release --example step_floor -- 2 0.5`): rapier in f64, not a command's JSON, so checked
/// here rather than through the manifest.
#[test]
fn the_step_floor_table_is_what_rapier_gives() {
    let doc = std::fs::read_to_string(root().join("docs/convergence.md")).expect("the doc");
    let rows = pma_leg::tools::step_floor(2.0, 0.5, &pma_leg::tools::STEP_FLOOR_SUBSTEPS)
        .expect("the swing");
    let missing: Vec<String> = rows
        .iter()
        .map(|r| r.markdown_row())
        .filter(|r| !doc.contains(r.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/convergence.md should have:\n{}",
        missing.join("\n")
    );
}

/// Regression (stop 74): cooperative.md's compare-modes table held another table's row with
/// the same label, which the row-by-row check passed.
#[test]
fn a_table_row_found_in_another_table_is_misplaced() {
    let figure: Figure = toml::from_str(
        r#"doc = "d.md"
command = ["compare-modes"]
rows_of = "x.md""#,
    )
    .expect("figure");
    let tables = |text| -> Vec<(&Figure, Vec<String>)> {
        table_groups(text)
            .into_iter()
            .map(|rows| (&figure, rows))
            .collect()
    };
    let made = "| a | b |\n|---|---|\n| x | 1 |\n| y | 2 |\n";
    assert!(misplaced_tables("d.md", made, &tables(made)).is_empty());
    let indented = "- item\n\n  | a | b |\n  |---|---|\n  | x | 1 |\n  | y | 2 |\n";
    assert!(misplaced_tables("d.md", indented, &tables(made)).is_empty());
    let apart = "| a | b |\n|---|---|\n| x | 1 |\n| y | 3 |\n\n| a | b |\n|---|---|\n| y | 2 |\n";
    assert_eq!(misplaced_tables("d.md", apart, &tables(made)).len(), 1);
    // Two tables of one figure: their order in the doc is the command's.
    let two = "| x | 1 |\n\n| y | 2 |\n";
    assert!(misplaced_tables("d.md", two, &tables(two)).is_empty());
    let swapped = "| y | 2 |\n\n| x | 1 |\n";
    assert_eq!(misplaced_tables("d.md", swapped, &tables(two)).len(), 1);
}

#[test]
fn a_template_takes_paths_factors_and_decimals() {
    let json: serde_json::Value =
        serde_json::from_str(r#"{"a": {"b": [0.5, 0.012345]}, "c": 2}"#).expect("json");
    assert_eq!(
        expand("| {a.b.1*1e3:.2} mm | {c:.0} |", &json),
        "| 12.35 mm | 2 |"
    );
    let named: serde_json::Value = serde_json::from_str(r#"{"s": ["DMSP-20"]}"#).expect("json");
    assert_eq!(expand("{s.0}, 1 m", &named), "DMSP-20, 1 m");
    assert_eq!(
        table_rows("| a | b |\n|---|---|\n| 1 | 2 |\ntext\n| 3 | 4 |\n"),
        ["| 1 | 2 |", "| 3 | 4 |"]
    );
}
