//! The mapping file: how a logger's columns become pam's record.
//!
//! A small TOML file (shipped for the public Festo set as
//! `examples/festo-10mm-isometric.toml`) says which column of the logger's
//! files holds time, pressure, load and contraction (or length), in which
//! unit, and which files make one record, each with the length the muscle
//! was held at when the record's protocol holds it:
//!
//! ```toml
//! header = false                       # the files have no header line
//! [columns]
//! load = { column = 1, unit = "N" }    # 1-based, or `name = "Force"`
//! pressure = { column = 2, unit = "kPa" }
//! time = { column = 3, unit = "s" }
//! [[record]]
//! name = "10cm_train"                  # written as 10cm_train.csv
//! rest_length = 8.3                    # in `length_unit` (default cm)
//! files = [
//!   { path = "10mm_10cm_Unkink_Test8.csv", held_length = 8.3 },
//!   { path = "10mm_10cm_kinked25_Test8.csv", held_length = 7.975 },
//! ]
//! ```
//!
//! Contraction comes from, in this order: a file's `held_length` (or
//! `contraction`), a `contraction` column, or a `length` column; lengths
//! are turned into contraction `(rest − length)/rest` with the record's
//! `rest_length`.

use std::collections::BTreeSet;

use serde::Deserialize;

/// The mapping file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mapping {
    /// Whether the files' first line names the columns (required: a
    /// guess would drop a sample or read a header as data).
    pub header: bool,
    /// Field separator, one character (default `,`).
    #[serde(default = "comma")]
    pub delimiter: char,
    /// Unit of every length in the file: `mm`, `cm` or `m` (default `cm`).
    #[serde(default = "cm")]
    pub length_unit: String,
    /// Where each quantity is.
    pub columns: Columns,
    /// The records to write.
    #[serde(rename = "record")]
    pub records: Vec<RecordSpec>,
}

fn comma() -> char {
    ','
}
fn cm() -> String {
    "cm".into()
}

/// Where each quantity is in a logger's file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Columns {
    /// Time since the logger's start.
    pub time: Column,
    /// Gauge pressure.
    pub pressure: Column,
    /// Load on the muscle (the hung weight, or the measured force).
    pub load: Column,
    /// Contraction, when the logger records it.
    pub contraction: Option<Column>,
    /// The muscle's length, when the logger records it.
    pub length: Option<Column>,
}

/// One column: where, in which unit, and an optional affine correction
/// (`value·scale + offset`, applied before the unit conversion).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Column {
    /// 1-based column number.
    pub column: Option<usize>,
    /// Header name (needs `header = true`).
    pub name: Option<String>,
    /// Unit of the values.
    pub unit: String,
    /// Factor applied to the raw value (default 1).
    #[serde(default = "one")]
    pub scale: f64,
    /// Added to the scaled value, in the column's unit (default 0).
    #[serde(default)]
    pub offset: f64,
}

fn one() -> f64 {
    1.0
}

/// One record: files joined in order.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordSpec {
    /// Output name (`NAME.csv`): letters, digits, `-`, `_`, `.`.
    pub name: String,
    /// Rest length, the reference of contraction (in `length_unit`).
    pub rest_length: Option<f64>,
    /// The files, in time order.
    pub files: Vec<FileSpec>,
}

/// One logger file of a record.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileSpec {
    /// Path, relative to the data directory.
    pub path: String,
    /// Length the muscle was held at over this file (isometric tests).
    pub held_length: Option<f64>,
    /// Contraction held over this file (instead of `held_length`).
    pub contraction: Option<f64>,
}

/// A quantity's unit and its factor to pam's unit.
pub fn unit_factor(quantity: &str, unit: &str) -> Option<f64> {
    let u = unit.trim();
    let f = match (quantity, u) {
        ("time", "s") => 1.0,
        ("time", "ms") => 1e-3,
        ("time", "us") => 1e-6,
        ("time", "min") => 60.0,
        ("pressure", "MPa") => 1.0,
        ("pressure", "kPa") => 1e-3,
        ("pressure", "Pa") => 1e-6,
        ("pressure", "bar") => 0.1,
        ("pressure", "psi") => 0.006_894_757,
        ("load", "N") => 1.0,
        ("load", "kN") => 1e3,
        ("load", "kgf") => 9.806_65,
        ("load", "lbf") => 4.448_222,
        ("contraction", "fraction") => 1.0,
        ("contraction", "percent") => 0.01,
        ("length", "m") => 1.0,
        ("length", "cm") => 1e-2,
        ("length", "mm") => 1e-3,
        _ => return None,
    };
    Some(f)
}

/// The units accepted for a quantity, for messages.
pub fn units_of(quantity: &str) -> &'static str {
    match quantity {
        "time" => "s, ms, us, min",
        "pressure" => "MPa, kPa, Pa, bar, psi",
        "load" => "N, kN, kgf, lbf",
        "contraction" => "fraction, percent",
        _ => "m, cm, mm",
    }
}

impl Mapping {
    /// Parse and check a mapping file's text; the error says what is wrong
    /// and, for a TOML error, where: `(line, column)`, 1-based.
    pub fn parse(text: &str) -> Result<Mapping, (Option<(u64, u64)>, String)> {
        let m: Mapping = toml::from_str(text).map_err(|e| {
            let at = e.span().map(|sp| {
                let before = &text[..sp.start.min(text.len())];
                let line = before.matches('\n').count() as u64 + 1;
                let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) as u64 + 1;
                (line, col)
            });
            (at, e.message().trim().to_string())
        })?;
        m.check().map_err(|why| (None, why))?;
        Ok(m)
    }

    fn check(&self) -> Result<(), String> {
        let d = self.delimiter;
        let usable = d == '\t' || (d.is_ascii() && !d.is_ascii_control() && !"\"#".contains(d));
        if !usable {
            return Err(format!(
                "delimiter `{}`: must be one ASCII character other than `\"` and `#` (a comma, \
                 a semicolon, a tab…)",
                d.escape_default()
            ));
        }
        if unit_factor("length", &self.length_unit).is_none() {
            return Err(format!(
                "length_unit `{}`: expected one of {}",
                self.length_unit,
                units_of("length")
            ));
        }
        let c = &self.columns;
        let mut named: Vec<(&str, &Column)> = vec![
            ("time", &c.time),
            ("pressure", &c.pressure),
            ("load", &c.load),
        ];
        if let Some(x) = &c.contraction {
            named.push(("contraction", x));
        }
        if let Some(x) = &c.length {
            named.push(("length", x));
        }
        let mut used = BTreeSet::new();
        for (q, col) in &named {
            if unit_factor(q, &col.unit).is_none() {
                return Err(format!(
                    "columns.{q}: unit `{}` is not known (one of {})",
                    col.unit,
                    units_of(q)
                ));
            }
            match (&col.column, &col.name) {
                (Some(0), _) => return Err(format!("columns.{q}: columns count from 1")),
                (Some(_), Some(_)) | (None, None) => {
                    return Err(format!(
                        "columns.{q}: give either `column` (1-based) or `name`"
                    ))
                }
                (None, Some(_)) if !self.header => {
                    return Err(format!(
                        "columns.{q}: `name` needs `header = true`; give `column` (1-based)"
                    ))
                }
                _ => {}
            }
            if !(col.scale.is_finite() && col.scale != 0.0 && col.offset.is_finite()) {
                return Err(format!(
                    "columns.{q}: scale must be finite and non-zero, offset finite"
                ));
            }
            let key = col
                .column
                .map(|n| n.to_string())
                .or(col.name.clone())
                .unwrap_or_default();
            if !used.insert(key.clone()) {
                return Err(format!("columns.{q}: column `{key}` is mapped twice"));
            }
        }
        if self.records.is_empty() {
            return Err("no [[record]]: name at least one record and its files".into());
        }
        let mut names = BTreeSet::new();
        for r in &self.records {
            let ok = !r.name.is_empty()
                && r.name
                    .chars()
                    .all(|ch| ch.is_ascii_alphanumeric() || "-_.".contains(ch))
                && !r.name.starts_with('.');
            if !ok {
                return Err(format!(
                    "record `{}`: a name is letters, digits, `-`, `_` and `.`, not starting with `.`",
                    r.name
                ));
            }
            if !names.insert(r.name.as_str()) {
                return Err(format!("record `{}`: named twice", r.name));
            }
            if r.files.is_empty() {
                return Err(format!("record `{}`: no files", r.name));
            }
            if let Some(l) = r.rest_length {
                if !(l.is_finite() && l > 0.0) {
                    return Err(format!("record `{}`: rest_length must be > 0", r.name));
                }
            }
            for f in &r.files {
                let wants_rest = f.held_length.is_some()
                    || (f.contraction.is_none() && c.contraction.is_none() && c.length.is_some());
                if wants_rest && r.rest_length.is_none() {
                    return Err(format!(
                        "record `{}`, file `{}`: a length needs the record's rest_length",
                        r.name, f.path
                    ));
                }
                if f.held_length.is_some() && f.contraction.is_some() {
                    return Err(format!(
                        "record `{}`, file `{}`: give held_length or contraction, not both",
                        r.name, f.path
                    ));
                }
                if f.held_length.is_none()
                    && f.contraction.is_none()
                    && c.contraction.is_none()
                    && c.length.is_none()
                {
                    return Err(format!(
                        "record `{}`, file `{}`: no contraction: map a `contraction` or \
                         `length` column, or give the file's held_length",
                        r.name, f.path
                    ));
                }
                if let Some(v) = f.held_length.filter(|v| !(v.is_finite() && *v > 0.0)) {
                    return Err(format!(
                        "record `{}`, file `{}`: held_length {v} must be > 0",
                        r.name, f.path
                    ));
                }
                if let Some(v) = f.contraction.filter(|v| !(v.is_finite() && v.abs() < 1.0)) {
                    return Err(format!(
                        "record `{}`, file `{}`: contraction {v} must be a fraction in (−1, 1)",
                        r.name, f.path
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OK: &str = r#"
header = false
[columns]
load = { column = 1, unit = "N" }
pressure = { column = 2, unit = "kPa" }
time = { column = 3, unit = "s" }
[[record]]
name = "a"
rest_length = 8.3
files = [{ path = "x.csv", held_length = 8.3 }]
"#;

    #[test]
    fn a_good_mapping_parses() {
        let m = Mapping::parse(OK).unwrap();
        assert_eq!(m.records[0].files[0].held_length, Some(8.3));
        assert!(!m.header);
    }

    #[test]
    fn mistakes_are_named() {
        for (from, to, want) in [
            ("\"kPa\"", "\"kpa\"", "unit `kpa` is not known"),
            ("column = 2", "column = 1", "mapped twice"),
            ("column = 3", "column = 0", "count from 1"),
            ("rest_length = 8.3", "", "needs the record's rest_length"),
            ("name = \"a\"", "name = \"../a\"", "a name is letters"),
            ("held_length = 8.3", "held_length = -1", "must be > 0"),
            (
                "header = false",
                "header = false\nbogus = 1",
                "unknown field",
            ),
            (
                "header = false",
                "header = false\ndelimiter = \"#\"",
                "delimiter `#`",
            ),
            ("header = false", "", "missing field `header`"),
        ] {
            let (_, e) = Mapping::parse(&OK.replacen(from, to, 1)).unwrap_err();
            assert!(e.contains(want), "{from} → {to}: {e}");
        }
    }
}
