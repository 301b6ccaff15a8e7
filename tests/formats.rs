//! The CSV columns and Rerun series tables of `docs/formats.md` are generated from the
//! samples' schemas: this test fails when one drifts. `PMA_BLESS=1 cargo test --test
//! formats` rewrites them.
use pma_bench::Sample;
use pma_leg::{LegSample, TrainerSample};
use pma_loop::Schema;
use pma_studies::pendulum::PendulumSample;

const FORMATS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/formats.md");

/// Each generated table: its marker in the docs and its schema (a leading `t_s`).
fn tables() -> Vec<(&'static str, Schema)> {
    let with_time = |s: Schema| {
        let mut t = Schema::new();
        t.push(
            "",
            "t_s",
            "time (s); in Rerun the timeline `sim_time`, not a series",
        );
        t.channels[0].path = "sim_time".to_owned();
        t.channels.extend(s.channels);
        t
    };
    vec![
        (
            "simulate",
            with_time(LegSample::schema(&["{muscle}".to_owned()], false)),
        ),
        ("simulate-treadmill", {
            let mut s = LegSample::foot_schema();
            s.channels.extend(TrainerSample::ground_schema().channels);
            s
        }),
        ("pendulum", with_time(PendulumSample::schema())),
        ("single", with_time(Sample::schema())),
    ]
}

/// `text` with the block after `<!-- schema NAME -->` (up to `<!-- /schema -->`) replaced
/// by `table`; `None` if the markers are missing.
fn replace_block(text: &str, name: &str, table: &str) -> Option<String> {
    let open = format!("<!-- schema {name} -->\n");
    let start = text.find(&open)? + open.len();
    let end = start + text[start..].find("<!-- /schema -->")?;
    Some(format!("{}{table}{}", &text[..start], &text[end..]))
}

#[test]
fn the_formats_tables_are_the_schemas() {
    let doc = std::fs::read_to_string(FORMATS).expect("docs/formats.md");
    let mut want = doc.clone();
    for (name, schema) in tables() {
        want = replace_block(&want, name, &schema.markdown())
            .unwrap_or_else(|| panic!("docs/formats.md has no `<!-- schema {name} -->` block"));
    }
    if std::env::var_os("PMA_BLESS").is_some() {
        std::fs::write(FORMATS, &want).expect("write docs/formats.md");
        return;
    }
    assert!(
        want == doc,
        "docs/formats.md's column tables differ from the schemas: run `PMA_BLESS=1 cargo test --test formats` and review the diff"
    );
}
