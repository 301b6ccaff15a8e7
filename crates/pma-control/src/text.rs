//! One-line messages for the project's TOML files.

/// A TOML error of `text` as one line: `line L: message`, without the source excerpt the
/// parser adds (which quotes the file's first line, a comment, for a missing section).
pub fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let message = one_line(e.message());
    match e.span() {
        Some(span) if !(span.start == 0 && span.end == 0) => {
            let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
            format!("line {line}: {message}")
        }
        _ => message,
    }
}

/// Any message on one line (whitespace runs and line breaks become one space).
pub fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_section_does_not_quote_the_first_comment() {
        #[derive(serde::Deserialize, Debug)]
        #[allow(dead_code)]
        struct F {
            gait: u32,
        }
        let text = "# a scenario\nname = 1\n";
        let e = toml::from_str::<F>(text).unwrap_err();
        let m = toml_error(text, &e);
        assert!(m.contains("gait") && !m.contains("a scenario"), "{m}");
        let text = "# a scenario\ngait = \"x\"\n";
        let e = toml::from_str::<F>(text).unwrap_err();
        let m = toml_error(text, &e);
        assert!(m.starts_with("line 2:"), "{m}");
    }
}
