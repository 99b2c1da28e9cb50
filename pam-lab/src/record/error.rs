//! What is wrong with a record, and where: file, line, column, reason.

use std::fmt;

use super::*;

/// What is wrong with an input.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum DataErrorKind {
    /// The file could not be read.
    Io(String),
    /// The file has no header line.
    NoHeader,
    /// The first line holds numbers: the header is missing.
    HeaderIsData,
    /// A required column is not in the header.
    MissingColumn,
    /// A column is named twice in the header.
    DuplicateColumn,
    /// The header is split by another character than a comma.
    WrongSeparator(char),
    /// A column's unit is not the one the format needs (`pressure_kpa`).
    WrongUnit {
        /// The header name found.
        found: String,
        /// What to do.
        hint: &'static str,
    },
    /// Not text: a NUL byte or invalid UTF-8 at this byte offset.
    Binary {
        /// Byte offset of the first offending byte.
        offset: u64,
    },
    /// The file is larger than [`MAX_BYTES`].
    TooLarge,
    /// The file has more than [`MAX_ROWS`] samples.
    TooManyRows,
    /// A row has fewer fields than the column needs, or the field is empty.
    MissingField,
    /// A row has more fields than the header.
    ExtraFields {
        /// Fields in this row.
        fields: usize,
        /// Fields in the header.
        header: usize,
    },
    /// A field is not a number; the field is given.
    NotANumber(String),
    /// A field is NaN or infinite.
    NonFinite,
    /// Time is smaller than on the previous sample.
    TimeBackwards {
        /// Previous time, s.
        previous_s: f64,
        /// This row's time, s.
        t_s: f64,
    },
    /// A value no muscle or rig can produce; the text says what is allowed.
    Impossible {
        /// The value read.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// A value that is the right quantity in the wrong unit (kPa for MPa,
    /// per cent for a fraction).
    LikelyUnit {
        /// The value read.
        value: f64,
        /// The unit it looks like and what the column needs.
        hint: &'static str,
    },
    /// The file has a header but no samples.
    NoSamples,
    /// Too few samples to identify the model; the text says which group.
    TooFewSamples(String),
    /// A channel contradicts how a muscle behaves; the text says how, and
    /// the likely fix.
    Implausible(String),
    /// Every time stamp is the same.
    TimeNeverAdvances,
    /// A channel that must vary holds one value over the whole record.
    Constant {
        /// The value.
        value: f64,
    },
    /// A sensor reads one value for a long stretch while the others move.
    Stuck {
        /// The value.
        value: f64,
        /// Last line of the stretch.
        until_line: u64,
        /// Samples in the stretch.
        samples: usize,
        /// Fraction of the record.
        fraction: f64,
        /// What moved meanwhile.
        moved: String,
    },
}

/// An input defect, located: file, line and column.
#[derive(Clone, Debug, PartialEq)]
pub struct DataError {
    /// The file (or source label).
    pub file: String,
    /// 1-based line, 0 when the defect is about the whole file.
    pub line: u64,
    /// The column concerned, if one is.
    pub column: Option<String>,
    /// What is wrong.
    pub kind: DataErrorKind,
}

/// A number as a person reads it: the shortest text that reads back to the
/// same value, in exponent form when very large or small (`1e30`, not 31
/// digits).
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e7).contains(&a) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// [`num`] for an `f32`: its own shortest text (`0.49886334`, not the
/// `f64` widening's `0.4988633394241333`).
pub fn num32(v: f32) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e7).contains(&a) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

impl fmt::Display for DataError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if self.line > 0 {
            write!(f, ":{}", self.line)?;
        }
        if let Some(c) = &self.column {
            write!(f, ": column `{c}`")?;
        }
        write!(f, ": ")?;
        let need = COLUMNS.join(",");
        match &self.kind {
            DataErrorKind::Io(e) => write!(f, "cannot read: {e}"),
            DataErrorKind::NoHeader => write!(f, "no header line (expected `{need}`)"),
            DataErrorKind::HeaderIsData => write!(
                f,
                "the first line holds numbers, not column names: add the header `{need}`"
            ),
            DataErrorKind::MissingColumn => {
                write!(f, "missing from the header (need `{need}`)")
            }
            DataErrorKind::DuplicateColumn => write!(f, "named twice in the header"),
            DataErrorKind::WrongSeparator(c) => write!(
                f,
                "the header is separated by `{}`, not by commas: save the file as \
                 comma-separated (`{need}`)",
                c.escape_default()
            ),
            DataErrorKind::WrongUnit { found, hint } => {
                write!(f, "header names `{found}`: {hint}")
            }
            DataErrorKind::Binary { offset } => write!(
                f,
                "not a text file (a NUL byte or invalid UTF-8 at byte {offset}): a CSV record is \
                 expected"
            ),
            DataErrorKind::TooLarge => write!(
                f,
                "larger than {} MiB: decimate the record or split it",
                MAX_BYTES >> 20
            ),
            DataErrorKind::TooManyRows => write!(
                f,
                "more than {MAX_ROWS} samples: decimate the record or split it"
            ),
            DataErrorKind::MissingField => write!(f, "row has no value for this column"),
            DataErrorKind::ExtraFields { fields, header } => write!(
                f,
                "row has {fields} fields, the header {header} (a decimal comma, or an unquoted \
                 comma in a field?)"
            ),
            DataErrorKind::NotANumber(s) => {
                let shown: String = s.chars().take(40).collect();
                let more = if s.chars().count() > 40 { "…" } else { "" };
                write!(f, "`{}{more}` is not a number", shown.escape_debug())
            }
            DataErrorKind::NonFinite => write!(f, "value is NaN or infinite"),
            DataErrorKind::TimeBackwards { previous_s, t_s } => write!(
                f,
                "time goes backwards ({} s after {} s on the previous sample)",
                num(*t_s),
                num(*previous_s)
            ),
            DataErrorKind::Impossible { value, allowed } => {
                write!(f, "physically impossible value {} ({allowed})", num(*value))
            }
            DataErrorKind::LikelyUnit { value, hint } => {
                write!(f, "value {} is out of range: {hint}", num(*value))
            }
            DataErrorKind::NoSamples => write!(f, "no samples after the header"),
            DataErrorKind::Implausible(what) => write!(f, "{what}"),
            DataErrorKind::TooFewSamples(what) => {
                write!(f, "too few samples to identify the model: {what}")
            }
            DataErrorKind::TimeNeverAdvances => write!(
                f,
                "every time stamp is the same: time must increase (seconds since the start)"
            ),
            DataErrorKind::Constant { value } => write!(
                f,
                "holds {} on every sample: the record needs this channel to vary (is the sensor \
                 connected?)",
                num(*value)
            ),
            DataErrorKind::Stuck {
                value,
                until_line,
                samples,
                fraction,
                moved,
            } => write!(
                f,
                "stuck at {} up to line {until_line} ({samples} samples, {:.0} % of the record) \
                 while {moved}: a sensor fault; cut that part out of the record",
                num(*value),
                100.0 * fraction
            ),
        }
    }
}

impl std::error::Error for DataError {}
