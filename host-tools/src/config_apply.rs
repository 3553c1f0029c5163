//! Applies a config fragment dollop wrote (calibrate, inspect) to a machine config's text:
//! keeps the file's comments and key order, lists every change old -> new, and validates the
//! result before anyone writes it. Reading and writing files, and the words of flags, belong
//! to the front ends.

use dollop::config::Config;
use std::fmt;
use toml_edit::{DocumentMut, Item, Table, Value};

/// Largest fragment or config text accepted, bytes: a fragment is a few lines and a machine
/// config a few kilobytes; anything near this is not one.
pub const MAX_TEXT_BYTES: usize = 1 << 20;

/// Which `[[inlet]]` a fragment's bare keys go to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InletRef {
    /// 0-based position in the config's `[[inlet]]` list.
    Index(usize),
    /// The inlet whose `material` is this name.
    Material(String),
}

impl InletRef {
    /// Reads `2` as an index and anything else as a material name.
    pub fn parse(s: &str) -> Self {
        s.parse::<usize>()
            .map_or_else(|_| Self::Material(s.to_string()), Self::Index)
    }

    /// Reads a comma-separated list, e.g. `0,1` or `paste A,paste B`.
    pub fn parse_list(s: &str) -> Vec<Self> {
        s.split(',').map(|x| Self::parse(x.trim())).collect()
    }
}

impl fmt::Display for InletRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Index(i) => write!(f, "inlet {i}"),
            Self::Material(m) => write!(f, "the inlet of material \"{m}\""),
        }
    }
}

/// One value the fragment changed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Change {
    /// Where, e.g. `motion.print_speed_mm_s` or `inlet[1] (paste B).rheology`.
    pub key: String,
    /// The value before, as written in the config; `None` where the key was not set.
    pub old: Option<String>,
    /// The value after, as written in the fragment.
    pub new: String,
}

impl fmt::Display for Change {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.old {
            Some(old) if *old == self.new => write!(f, "{}: {} (unchanged)", self.key, self.new),
            Some(old) => write!(f, "{}: {} -> {}", self.key, old, self.new),
            None => write!(f, "{}: (not set) -> {}", self.key, self.new),
        }
    }
}

/// The config with the fragment applied.
#[derive(Clone, Debug)]
pub struct Applied {
    /// The new config file's text.
    pub text: String,
    /// What changed, in the fragment's order.
    pub changes: Vec<Change>,
    /// The new config, parsed (validation is the caller's, as `config --check` does it).
    pub config: Config,
}

/// Why a fragment cannot be applied. Nothing is written when any of these is returned.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ApplyError {
    /// A text over [`MAX_TEXT_BYTES`].
    TooLarge {
        /// `fragment` or `config`.
        what: &'static str,
        /// Its size, bytes.
        bytes: usize,
    },
    /// Not TOML.
    Parse {
        /// `fragment` or `config`.
        what: &'static str,
        /// The parser's message, on one line.
        reason: String,
    },
    /// The fragment sets nothing.
    Empty,
    /// The fragment has keys of one `[[inlet]]` and no inlet was named.
    NeedInlet {
        /// The keys, e.g. `rheology`.
        keys: Vec<String>,
    },
    /// Inlets were named for the fragment's `[[inlet]]` tables, but not one per table.
    InletCount {
        /// The fragment's `[[inlet]]` tables.
        tables: usize,
        /// The inlets named.
        named: usize,
    },
    /// The named inlet is not in the config.
    NoSuchInlet {
        /// What was asked for.
        asked: InletRef,
        /// The config's materials, in order.
        materials: Vec<String>,
    },
    /// A fragment `[[inlet]]` table without `material`.
    InletWithoutMaterial {
        /// Its position among the fragment's `[[inlet]]` tables.
        position: usize,
    },
    /// The config has no `[[inlet]]` list (or something else under that name).
    NoInlets,
    /// A key the fragment sets is a table in one file and a value in the other.
    Shape {
        /// Where.
        key: String,
    },
    /// The result does not parse as a machine config.
    Invalid {
        /// The config loader's message.
        reason: String,
    },
}

impl fmt::Display for ApplyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooLarge { what, bytes } => write!(
                f,
                "the {what} is {bytes} bytes; a {what} is at most {MAX_TEXT_BYTES} bytes: is this the right file?"
            ),
            Self::Parse { what, reason } => write!(f, "the {what} is not valid TOML: {reason}"),
            Self::Empty => write!(f, "the fragment sets no key: nothing to apply"),
            Self::NeedInlet { keys } => write!(
                f,
                "the fragment sets {} of one [[inlet]]: say which inlet (its index from 0, or its material name)",
                keys.join(", ")
            ),
            Self::InletCount { tables, named } => write!(
                f,
                "the fragment has {tables} [[inlet]] tables but {named} inlets were named: name one per table, in order, or none to match them by material"
            ),
            Self::NoSuchInlet { asked, materials } => write!(
                f,
                "the config has no {asked}; its inlets are {}",
                materials
                    .iter()
                    .enumerate()
                    .map(|(i, m)| format!("{i} ({m})"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Self::InletWithoutMaterial { position } => write!(
                f,
                "the fragment's [[inlet]] number {} has no `material` key to say which inlet it corrects",
                position + 1
            ),
            Self::NoInlets => write!(f, "the config has no [[inlet]] tables to apply inlet keys to"),
            Self::Shape { key } => write!(
                f,
                "`{key}` is a table in one file and a single value in the other: the fragment does not fit this config"
            ),
            Self::Invalid { reason } => {
                write!(f, "the config with the fragment applied is not valid: {reason}")
            }
        }
    }
}

impl std::error::Error for ApplyError {}

/// Applies `fragment` to the config text `config`. Bare keys go to every inlet in `inlets`
/// (at least one is required when there are any: a syringe fragment goes to all inlets,
/// since the core takes syringes only when every inlet is one); `[[inlet]]` tables go, in
/// order, to the inlets named, or without names to the config's inlet of the same
/// `material`; other tables (`[motion]`, `[channel]`, ...) to the table of the same name.
/// The result is parsed as a [`Config`]; its validation against the core is the caller's.
pub fn apply(config: &str, fragment: &str, inlets: &[InletRef]) -> Result<Applied, ApplyError> {
    let mut doc = parse("config", config)?;
    let frag = parse("fragment", fragment)?;
    let mut changes = Vec::new();
    let bare: Vec<(&str, &Item)> = frag
        .iter()
        .filter(|(k, v)| *k != "inlet" && !v.is_table())
        .collect();
    if !bare.is_empty() {
        if inlets.is_empty() {
            return Err(ApplyError::NeedInlet {
                keys: bare.iter().map(|(k, _)| k.to_string()).collect(),
            });
        }
        for which in inlets {
            let (index, table) = inlet_table(&mut doc, which)?;
            let label = inlet_label(index, table);
            for (key, item) in &bare {
                changes.push(set(table, key, item, &label)?);
            }
        }
    }
    for (key, item) in frag.iter() {
        if key == "inlet" {
            let Some(list) = item.as_array_of_tables() else {
                return Err(ApplyError::Shape {
                    key: "inlet".into(),
                });
            };
            let by_name = inlets.is_empty() || !bare.is_empty();
            if !by_name && inlets.len() != list.len() {
                return Err(ApplyError::InletCount {
                    tables: list.len(),
                    named: inlets.len(),
                });
            }
            for (position, t) in list.iter().enumerate() {
                let which = if by_name {
                    let Some(material) = t.get("material").and_then(Item::as_str) else {
                        return Err(ApplyError::InletWithoutMaterial { position });
                    };
                    InletRef::Material(material.to_string())
                } else {
                    inlets[position].clone()
                };
                let (index, table) = inlet_table(&mut doc, &which)?;
                let label = inlet_label(index, table);
                // Matched by material, the name is already the config's; named by the user,
                // the fragment's material renames the inlet.
                for (k, v) in t.iter().filter(|(k, _)| !by_name || *k != "material") {
                    changes.push(set(table, k, v, &label)?);
                }
            }
        } else if let Some(t) = item.as_table() {
            let target = doc
                .entry(key)
                .or_insert_with(|| Item::Table(Table::new()))
                .as_table_mut()
                .ok_or_else(|| ApplyError::Shape { key: key.into() })?;
            for (k, v) in t.iter() {
                changes.push(set(target, k, v, key)?);
            }
        }
    }
    if changes.is_empty() {
        return Err(ApplyError::Empty);
    }
    let text = doc.to_string();
    let config: Config = toml::from_str(&text).map_err(|e| ApplyError::Invalid {
        reason: one_line(&e.to_string()),
    })?;
    Ok(Applied {
        text,
        changes,
        config,
    })
}

fn parse(what: &'static str, text: &str) -> Result<DocumentMut, ApplyError> {
    if text.len() > MAX_TEXT_BYTES {
        return Err(ApplyError::TooLarge {
            what,
            bytes: text.len(),
        });
    }
    text.parse::<DocumentMut>().map_err(|e| ApplyError::Parse {
        what,
        reason: one_line(&e.to_string()),
    })
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The config's `[[inlet]]` table `which` names, with its index.
fn inlet_table<'a>(
    doc: &'a mut DocumentMut,
    which: &InletRef,
) -> Result<(usize, &'a mut Table), ApplyError> {
    let list = doc
        .get_mut("inlet")
        .and_then(Item::as_array_of_tables_mut)
        .ok_or(ApplyError::NoInlets)?;
    let materials: Vec<String> = list
        .iter()
        .map(|t| {
            t.get("material")
                .and_then(Item::as_str)
                .unwrap_or("?")
                .to_string()
        })
        .collect();
    let index = match which {
        InletRef::Index(i) => Some(*i).filter(|&i| i < materials.len()),
        InletRef::Material(m) => materials.iter().position(|x| x == m),
    };
    let Some(index) = index else {
        return Err(ApplyError::NoSuchInlet {
            asked: which.clone(),
            materials,
        });
    };
    let table = list.get_mut(index).ok_or(ApplyError::NoInlets)?;
    Ok((index, table))
}

fn inlet_label(index: usize, table: &Table) -> String {
    match table.get("material").and_then(Item::as_str) {
        Some(m) => format!("inlet[{index}] ({m})"),
        None => format!("inlet[{index}]"),
    }
}

/// Sets `key` in `table` to the fragment's `item`, keeping the old entry's comments.
fn set(table: &mut Table, key: &str, item: &Item, label: &str) -> Result<Change, ApplyError> {
    let path = format!("{label}.{key}");
    let Some(new) = item.as_value() else {
        return Err(ApplyError::Shape { key: path });
    };
    let new_text = written(new);
    let old = match table.get_mut(key) {
        Some(existing) => {
            let Some(v) = existing.as_value_mut() else {
                return Err(ApplyError::Shape { key: path });
            };
            let old = written(v);
            let (prefix, suffix) = (v.decor().prefix().cloned(), v.decor().suffix().cloned());
            let mut value = new.clone();
            value.decor_mut().clear();
            if let Some(p) = prefix {
                value.decor_mut().set_prefix(p);
            }
            if let Some(s) = suffix {
                value.decor_mut().set_suffix(s);
            }
            *v = value;
            Some(old)
        }
        None => {
            let mut value = new.clone();
            value.decor_mut().clear();
            table.insert(key, Item::Value(value));
            None
        }
    };
    Ok(Change {
        key: path,
        old,
        new: new_text,
    })
}

/// A value as written, without its comments and spacing.
fn written(v: &Value) -> String {
    let mut v = v.clone();
    v.decor_mut().clear();
    v.to_string().trim().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    const CONFIG: &str = include_str!("example-config.toml");

    #[test]
    fn bare_keys_need_an_inlet() {
        let e = apply(CONFIG, "valve_open_delay_ms = 12.0\n", &[]).unwrap_err();
        assert!(
            matches!(e, ApplyError::NeedInlet { ref keys } if keys == &["valve_open_delay_ms"])
        );
    }

    #[test]
    fn comments_and_order_stay() {
        let a = apply(
            CONFIG,
            "# a comment\nvalve_open_delay_ms = 12.5\n",
            &[InletRef::Index(1)],
        )
        .unwrap();
        let before: Vec<&str> = CONFIG
            .lines()
            .filter(|l| l.trim_start().starts_with('#'))
            .collect();
        let after: Vec<&str> = a
            .text
            .lines()
            .filter(|l| l.trim_start().starts_with('#'))
            .collect();
        assert_eq!(before, after, "every comment kept, in order");
        assert_eq!(a.changes.len(), 1);
        assert_eq!(a.config.inlets[1].valve_open_delay_ms, 12.5);
        assert_eq!(CONFIG.lines().count(), a.text.lines().count());
    }

    #[test]
    fn inlet_tables_go_by_material_or_in_the_order_named() {
        let frag = "[[inlet]]\nmaterial = \"paste B (3.17 Pa s)\"\npressure_kpa = 7.5\n";
        let a = apply(CONFIG, frag, &[]).unwrap();
        assert!(format!("{:?}", a.config.inlets[1].pressure_kpa).contains("7.5"));
        assert_eq!(a.changes.len(), 1, "{:?}", a.changes);
        let frag = "[[inlet]]\nmaterial = \"puree\"\npressure_kpa = 7.5\n";
        let a = apply(CONFIG, frag, &[InletRef::Index(0)]).unwrap();
        assert_eq!(a.config.inlets[0].material, "puree");
        assert_eq!(a.changes.len(), 2, "{:?}", a.changes);
        assert!(matches!(
            apply(CONFIG, frag, &[InletRef::Index(0), InletRef::Index(1)]),
            Err(ApplyError::InletCount {
                tables: 1,
                named: 2
            })
        ));
    }

    #[test]
    fn unknown_inlet_names_the_ones_there_are() {
        let e = apply(
            CONFIG,
            "[[inlet]]\nmaterial = \"nope\"\npressure_kpa = 1.0\n",
            &[],
        )
        .unwrap_err();
        assert!(e.to_string().contains("0 ("), "{e}");
        let e = apply(CONFIG, "pressure_kpa = 1.0\n", &[InletRef::Index(9)]).unwrap_err();
        assert!(matches!(e, ApplyError::NoSuchInlet { .. }), "{e}");
    }

    #[test]
    fn bad_text_is_an_error() {
        assert!(matches!(
            apply(CONFIG, "this is = = not toml", &[]),
            Err(ApplyError::Parse {
                what: "fragment",
                ..
            })
        ));
        assert!(matches!(
            apply(CONFIG, "# only a comment\n", &[]),
            Err(ApplyError::Empty)
        ));
        assert!(matches!(
            apply(CONFIG, "[motion]\nprint_speed_mm_s = \"fast\"\n", &[]),
            Err(ApplyError::Invalid { .. })
        ));
        let big = "#".repeat(MAX_TEXT_BYTES + 1);
        assert!(matches!(
            apply(CONFIG, &big, &[]),
            Err(ApplyError::TooLarge {
                what: "fragment",
                ..
            })
        ));
        assert!(matches!(
            apply(CONFIG, "[motion.print_speed_mm_s]\nx = 1\n", &[]),
            Err(ApplyError::Shape { .. })
        ));
    }
}
