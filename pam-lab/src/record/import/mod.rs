//! Records as users have them: a logger's files, turned into pam's record.
//!
//! `pam-lab import MAP.toml` reads the files a [`mapping::Mapping`] names,
//! converts each column to pam's units (seconds, MPa, newtons, contraction
//! as a fraction of rest length), joins the files of one record in order
//! and writes `t_s,load_n,pressure_mpa,contraction` CSV that `fit`,
//! `simulate` and `diagnose` read.
//!
//! * **Segments.** Each file starts a new segment, and so does a logger
//!   clock that restarts inside a file (time smaller than on the previous
//!   sample): the segment's time is moved to continue the record's clock
//!   one sample interval after the last sample, a `# segment` comment line
//!   marks the seam in the output, and a warning says where it was.
//! * **Loads below zero** (a load cell's offset when the muscle is slack)
//!   are written as 0 N and counted in a warning: a muscle only pulls.
//! * Every other value is checked as `fit` checks its CSV; a bad field is
//!   refused with its file, line, column and reason, and nothing is written.

pub mod mapping;

use std::fmt;
use std::path::Path;

use crate::record::{self, num, Sample, MAX_BYTES, MAX_ROWS};
use mapping::{unit_factor, Column, Mapping, RecordSpec};

/// A refused input: where and why.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportError {
    /// The file (mapping or logger file).
    pub file: String,
    /// 1-based line, 0 for the whole file.
    pub line: u64,
    /// The column concerned (1-based number or header name).
    pub column: Option<String>,
    /// What is wrong, and the fix where there is one.
    pub why: String,
}

impl fmt::Display for ImportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if self.line > 0 {
            write!(f, ":{}", self.line)?;
        }
        if let Some(c) = &self.column {
            write!(f, ": column {c}")?;
        }
        write!(f, ": {}", self.why)
    }
}

impl std::error::Error for ImportError {}

/// One converted record.
#[derive(Clone, Debug, PartialEq)]
pub struct Imported {
    /// The record's name (the output is `NAME.csv`).
    pub name: String,
    /// The samples, pam's units, time strictly continuing across seams.
    pub samples: Vec<Sample>,
    /// Seams: `(index of the segment's first sample, what started it)`.
    pub segments: Vec<(usize, String)>,
    /// What the conversion changed or noticed (`file:line: …`).
    pub warnings: Vec<String>,
}

impl Imported {
    /// The record as pam's CSV, with a `# segment` comment at each seam.
    pub fn to_csv(&self) -> String {
        let mut out = String::with_capacity(self.samples.len() * 40);
        out.push_str("t_s,load_n,pressure_mpa,contraction\n");
        let mut seams = self.segments.iter().peekable();
        for (i, s) in self.samples.iter().enumerate() {
            while let Some((_, why)) = seams.next_if(|(at, _)| *at == i) {
                out.push_str("# ");
                out.push_str(crate::record::SEGMENT_COMMENT);
                out.push(' ');
                out.push_str(why);
                out.push('\n');
            }
            out.push_str(&format!(
                "{},{},{},{}\n",
                fmt6(s.t_s),
                fmt6(s.load_n),
                fmt6(s.pressure_mpa),
                fmt6(s.contraction)
            ));
        }
        out
    }
}

/// A value to 6 decimals, without trailing zeros.
fn fmt6(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// Read and check a mapping file.
pub fn read_mapping(path: &Path) -> Result<Mapping, ImportError> {
    let file = path.display().to_string();
    let err = |why: String| ImportError {
        file: file.clone(),
        line: 0,
        column: None,
        why,
    };
    let meta = std::fs::metadata(path).map_err(|e| err(format!("cannot read: {e}")))?;
    if meta.is_dir() || meta.len() > 1 << 20 {
        return Err(err(
            "not a mapping file (a directory, or larger than 1 MiB)".into(),
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
    Mapping::parse(&text).map_err(|(at, why)| match at {
        Some((line, column)) => ImportError {
            file: file.clone(),
            line,
            column: None,
            why: format!("column {column}: {why}"),
        },
        None => err(why),
    })
}

/// Convert every record of `mapping` (or those named in `only`), its files
/// found in `data_dir`.
pub fn import(
    mapping: &Mapping,
    data_dir: &Path,
    only: &[String],
) -> Result<Vec<Imported>, ImportError> {
    for name in only {
        if !mapping.records.iter().any(|r| &r.name == name) {
            let names: Vec<&str> = mapping.records.iter().map(|r| r.name.as_str()).collect();
            return Err(ImportError {
                file: "--record".into(),
                line: 0,
                column: None,
                why: format!(
                    "no record `{name}` in the mapping (it has: {})",
                    names.join(", ")
                ),
            });
        }
    }
    mapping
        .records
        .iter()
        .filter(|r| only.is_empty() || only.contains(&r.name))
        .map(|r| import_record(mapping, r, data_dir))
        .collect()
}

/// Where a mapped column is, resolved against a file's header.
struct Resolved {
    index: usize,
    label: String,
    factor: f64,
    scale: f64,
    offset: f64,
}

fn resolve(
    quantity: &str,
    col: &Column,
    header: Option<&csv::StringRecord>,
    file: &str,
) -> Result<Resolved, ImportError> {
    let factor = unit_factor(quantity, &col.unit).unwrap_or(1.0);
    let (index, label) = match (&col.column, &col.name, header) {
        (Some(n), _, _) => (n - 1, n.to_string()),
        (None, Some(name), Some(h)) => match h.iter().position(|f| f.trim() == name) {
            Some(i) => (i, format!("`{name}`")),
            None => {
                return Err(ImportError {
                    file: file.into(),
                    line: 1,
                    column: Some(format!("`{name}`")),
                    why: format!(
                        "not in the header (it names: {}); fix columns.{quantity} in the mapping",
                        h.iter().collect::<Vec<_>>().join(", ")
                    ),
                })
            }
        },
        _ => unreachable_column(file)?,
    };
    Ok(Resolved {
        index,
        label,
        factor,
        scale: col.scale,
        offset: col.offset,
    })
}

/// A mapping that passed its check always names a column; this keeps the
/// function total without a panic.
fn unreachable_column(file: &str) -> Result<(usize, String), ImportError> {
    Err(ImportError {
        file: file.into(),
        line: 0,
        column: None,
        why: "the mapping names no column for a quantity".into(),
    })
}

fn import_record(
    mapping: &Mapping,
    spec: &RecordSpec,
    data_dir: &Path,
) -> Result<Imported, ImportError> {
    let length_factor = unit_factor("length", &mapping.length_unit).unwrap_or(1e-2);
    let mut out = Imported {
        name: spec.name.clone(),
        samples: Vec::new(),
        segments: Vec::new(),
        warnings: Vec::new(),
    };
    let mut negative_loads = 0usize;
    let mut most_positive = 0.0f64;
    let mut most_negative = 0.0f64;
    let mut first_negative = String::new();
    for f in &spec.files {
        let path = data_dir.join(&f.path);
        let file = path.display().to_string();
        let err = |line: u64, column: Option<String>, why: String| ImportError {
            file: file.clone(),
            line,
            column,
            why,
        };
        let meta =
            std::fs::metadata(&path).map_err(|e| err(0, None, format!("cannot read: {e}")))?;
        if meta.is_dir() {
            return Err(err(0, None, "is a directory, not a logger file".into()));
        }
        if meta.len() > MAX_BYTES {
            return Err(err(0, None, format!("larger than {} MiB", MAX_BYTES >> 20)));
        }
        let bytes = std::fs::read(&path).map_err(|e| err(0, None, format!("cannot read: {e}")))?;
        if let Some(at) = bytes.iter().position(|b| *b == 0) {
            return Err(err(
                0,
                None,
                format!("not a text file (a NUL byte at byte {})", at + 1),
            ));
        }
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(mapping.header)
            .delimiter(u8::try_from(u32::from(mapping.delimiter)).unwrap_or(b','))
            .flexible(true)
            .trim(csv::Trim::All)
            .comment(Some(b'#'))
            .from_reader(bytes.as_slice());
        let header = if mapping.header {
            Some(
                reader
                    .headers()
                    .map_err(|e| {
                        let line = e.position().map_or(1, |p| p.line());
                        err(line, None, format!("cannot read the header: {e}"))
                    })?
                    .clone(),
            )
        } else {
            None
        };
        let c = &mapping.columns;
        let time = resolve("time", &c.time, header.as_ref(), &file)?;
        let pressure = resolve("pressure", &c.pressure, header.as_ref(), &file)?;
        let load = resolve("load", &c.load, header.as_ref(), &file)?;
        let rest_m = spec.rest_length.map(|l| l * length_factor);
        // The file's contraction: held, or a column.
        enum Source {
            Held(f64),
            Contraction(Resolved),
            Length(Resolved, f64),
        }
        let source = match (f.held_length, f.contraction, &c.contraction, &c.length) {
            (Some(l), _, _, _) => {
                let rest = rest_m.unwrap_or(1.0);
                Source::Held((rest - l * length_factor) / rest)
            }
            (None, Some(x), _, _) => Source::Held(x),
            (None, None, Some(col), _) => {
                Source::Contraction(resolve("contraction", col, header.as_ref(), &file)?)
            }
            (None, None, None, Some(col)) => Source::Length(
                resolve("length", col, header.as_ref(), &file)?,
                rest_m.unwrap_or(1.0),
            ),
            (None, None, None, None) => {
                return Err(err(0, None, "no contraction for this file".into()))
            }
        };
        // A new segment at each file.
        // The seam's text goes into a `#` comment line: one line.
        let shown = f.path.replace(['\n', '\r'], " ");
        let mut seam = Some(format!("{shown} (new file)"));
        let mut previous_raw: Option<f64> = None;
        let mut shift = 0.0;
        for row in reader.records() {
            let row = row.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line());
                err(line, None, format!("cannot read: {e}"))
            })?;
            let line = row.position().map_or(0, |p| p.line());
            if row.iter().all(str::is_empty) {
                continue;
            }
            let value = |r: &Resolved| -> Result<f64, ImportError> {
                let field = row.get(r.index).ok_or_else(|| {
                    err(
                        line,
                        Some(r.label.clone()),
                        format!(
                            "missing: the row has {} fields (is the delimiter `{}` right?)",
                            row.len(),
                            mapping.delimiter
                        ),
                    )
                })?;
                let v: f64 = field.parse().map_err(|_| {
                    err(
                        line,
                        Some(r.label.clone()),
                        format!("`{field}` is not a number"),
                    )
                })?;
                if !v.is_finite() {
                    return Err(err(
                        line,
                        Some(r.label.clone()),
                        format!("`{field}` is not finite"),
                    ));
                }
                Ok((v * r.scale + r.offset) * r.factor)
            };
            let t_raw = value(&time)?;
            let mut load_n = value(&load)?;
            let pressure_mpa = value(&pressure)?;
            let contraction = match &source {
                Source::Held(x) => *x,
                Source::Contraction(r) => value(r)?,
                Source::Length(r, rest) => (rest - value(r)?) / rest,
            };
            if let Some(prev) = previous_raw {
                if t_raw < prev {
                    let why = format!(
                        "{shown}:{line}: the logger's clock restarts ({} s after {} s)",
                        num(t_raw),
                        num(prev)
                    );
                    out.warnings.push(format!(
                        "{file}:{line}: the logger's clock restarts ({} s after {} s): a new \
                         segment from here, its time continued from the record's",
                        num(t_raw),
                        num(prev)
                    ));
                    seam = Some(why);
                }
            }
            previous_raw = Some(t_raw);
            if seam.is_some() {
                // Continue the record's clock one sample interval on.
                let dt = typical_interval(&out.samples);
                let next = out.samples.last().map_or(0.0, |s| s.t_s + dt);
                shift = next - t_raw;
                if let Some(why) = seam.take() {
                    out.segments.push((out.samples.len(), why));
                }
            }
            most_positive = most_positive.max(load_n);
            if load_n < 0.0 {
                if negative_loads == 0 {
                    first_negative = format!("{file}:{line}");
                }
                negative_loads += 1;
                most_negative = most_negative.min(load_n);
                load_n = 0.0;
            }
            let s = Sample {
                t_s: t_raw + shift,
                load_n,
                pressure_mpa,
                contraction,
            };
            if let Err((column, v, allowed)) = record::check_physical(&s) {
                // Name the logger's column (or the mapping's held value).
                let (label, fix) = match (column, &source) {
                    ("load_n", _) => (Some(load.label.clone()), "the load column's unit"),
                    ("pressure_mpa", _) => {
                        (Some(pressure.label.clone()), "the pressure column's unit")
                    }
                    (_, Source::Contraction(r) | Source::Length(r, _)) => (
                        Some(r.label.clone()),
                        "the contraction or length column's unit",
                    ),
                    _ => (None, "this file's held_length and the record's rest_length"),
                };
                return Err(err(
                    line,
                    label,
                    format!(
                        "converted {column} {} is impossible ({allowed}): check {fix} in the mapping",
                        num(v)
                    ),
                ));
            }
            if let Some(last) = out.samples.last() {
                if s.t_s < last.t_s {
                    return Err(err(
                        line,
                        Some(time.label.clone()),
                        "time goes backwards".into(),
                    ));
                }
            }
            out.samples.push(s);
            if out.samples.len() > MAX_ROWS {
                return Err(err(
                    line,
                    None,
                    format!(
                        "the record `{}` has more than {MAX_ROWS} samples: decimate it",
                        spec.name
                    ),
                ));
            }
        }
    }
    if -most_negative > most_positive {
        // Not an offset on a slack muscle (a few newtons below a pull of
        // hundreds): the muscle's pull itself reads negative.
        return Err(ImportError {
            file: first_negative,
            line: 0,
            column: None,
            why: format!(
                "the load reaches {} N but never more than {} N in record `{}`: a muscle only \
                 pulls; is the load cell's sign reversed? set `scale = -1` for columns.load in \
                 the mapping",
                num(most_negative),
                num(most_positive),
                spec.name
            ),
        });
    }
    if negative_loads > 0 {
        out.warnings.push(format!(
            "{first_negative}: {negative_loads} load readings below 0 N (down to {} N, a load \
             cell's offset on a slack muscle) written as 0 N",
            num(most_negative)
        ));
    }
    if out.samples.len() < 2 {
        return Err(ImportError {
            file: spec.name.clone(),
            line: 0,
            column: None,
            why: "the record's files hold fewer than two samples".into(),
        });
    }
    Ok(out)
}

/// The median time step of the last samples (1 ms when there are none).
fn typical_interval(samples: &[Sample]) -> f64 {
    let tail = &samples[samples.len().saturating_sub(101)..];
    let mut d: Vec<f64> = tail
        .windows(2)
        .map(|w| w[1].t_s - w[0].t_s)
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return 1e-3;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}
