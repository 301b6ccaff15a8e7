//! Signals named once: a sample type lists its channels (name, unit, path in a Rerun
//! recording, one line of documentation) in a [`Schema`], and writes its values in that
//! order. CSV headers, Rerun series and the tables of `docs/formats.md` all read the
//! schema, so adding a signal is one line in it and one value.

/// One channel of a sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// Its CSV column (units in the name: `angle_deg`, `pressure_cmd_pa`).
    pub name: String,
    /// Its entity path in a Rerun recording (`joints/hip/angle_deg`).
    pub path: String,
    /// What it is, on one line (the series' legend and the docs).
    pub doc: String,
}

/// The channels of a sample type, in the order its values come.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Schema {
    /// The channels.
    pub channels: Vec<Channel>,
}

impl Schema {
    /// An empty schema.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a channel whose Rerun path is its name under `group` (`""`: at the root).
    pub fn push(&mut self, group: &str, name: &str, doc: &str) -> &mut Self {
        let path = if group.is_empty() {
            name.to_owned()
        } else {
            format!("{group}/{name}")
        };
        self.channels.push(Channel {
            name: name.to_owned(),
            path,
            doc: doc.to_owned(),
        });
        self
    }

    /// Adds a channel of a named part (a joint, a muscle): its column is
    /// `<part>_<name>`, its path `<group>/<part>/<name>`, its doc prefixed with the part.
    pub fn push_part(&mut self, group: &str, part: &str, name: &str, doc: &str) -> &mut Self {
        self.channels.push(Channel {
            name: format!("{part}_{name}"),
            path: format!("{group}/{part}/{name}"),
            doc: format!("{part} {doc}"),
        });
        self
    }

    /// The same channels for one of several like parts (a trainer's `left` leg): columns
    /// `<prefix>_<name>`, paths `<prefix>/<path>`, docs prefixed.
    pub fn prefixed(&self, prefix: &str) -> Schema {
        Schema {
            channels: self
                .channels
                .iter()
                .map(|c| Channel {
                    name: format!("{prefix}_{}", c.name),
                    path: format!("{prefix}/{}", c.path),
                    doc: format!("{prefix} {}", c.doc),
                })
                .collect(),
        }
    }

    /// Number of channels.
    pub fn len(&self) -> usize {
        self.channels.len()
    }

    /// Whether it has no channel.
    pub fn is_empty(&self) -> bool {
        self.channels.is_empty()
    }

    /// The CSV header.
    pub fn columns(&self) -> Vec<String> {
        self.channels.iter().map(|c| c.name.clone()).collect()
    }

    /// A Markdown table of the channels (column, Rerun path, meaning), for the docs.
    pub fn markdown(&self) -> String {
        let mut md = String::from("| column | Rerun path | what |\n|---|---|---|\n");
        for c in &self.channels {
            md.push_str(&format!("| `{}` | `{}` | {} |\n", c.name, c.path, c.doc));
        }
        md
    }
}

/// A sample that writes its values in the order of its schema, without allocating.
pub trait Signals {
    /// Writes the values; `out` has the schema's length.
    fn values(&self, out: &mut [f64]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_schema_names_columns_paths_and_docs_once() {
        let mut s = Schema::new();
        s.push("", "t_s", "time (s)")
            .push_part("joints", "hip", "angle_deg", "angle (deg)");
        assert_eq!(s.columns(), ["t_s", "hip_angle_deg"]);
        assert_eq!(s.channels[1].path, "joints/hip/angle_deg");
        assert_eq!(s.channels[1].doc, "hip angle (deg)");
        assert!(s
            .markdown()
            .contains("| `hip_angle_deg` | `joints/hip/angle_deg` |"));
        let left = s.prefixed("left");
        assert_eq!(left.columns(), ["left_t_s", "left_hip_angle_deg"]);
        assert_eq!(left.channels[1].path, "left/joints/hip/angle_deg");
        assert_eq!(left.channels[1].doc, "left hip angle (deg)");
    }
}
