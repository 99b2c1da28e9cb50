//! Reading and validating measurement CSV files.
//!
//! Format: a header naming at least `t_s,load_n,pressure_mpa,contraction` (in
//! any order; other columns are ignored), then one sample per row. Lines
//! starting with `#` are comments; blank lines are skipped.
//!
//! * `t_s`: time, s, non-decreasing.
//! * `load_n`: load on the muscle, N (isotonic tests: the hung load; isometric
//!   tests: the measured force).
//! * `pressure_mpa`: gauge pressure, MPa.
//! * `contraction`: contraction as a fraction of the rest length.
//!
//! Every defect is a [`DataError`] naming the file, the line (1-based, as an
//! editor shows it) and the column.

use std::fmt;
use std::io::Read;
use std::path::Path;

/// The columns the tools need, in the order of [`Sample`]'s fields.
pub const COLUMNS: [&str; 4] = ["t_s", "load_n", "pressure_mpa", "contraction"];

/// Lowest physically possible gauge pressure, MPa: absolute vacuum.
pub const MIN_PRESSURE_MPA: f64 = -0.101_325;
/// Highest pressure accepted, MPa (the model's own limit on `Pmax`).
pub const MAX_PRESSURE_MPA: f64 = 10.0;
/// Highest load accepted, N. A muscle only pulls, so loads are `>= 0`.
pub const MAX_LOAD_N: f64 = 100_000.0;

/// One measurement.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Load, N.
    pub load_n: f64,
    /// Gauge pressure, MPa.
    pub pressure_mpa: f64,
    /// Contraction, fraction of rest length.
    pub contraction: f64,
}

/// A validated measurement record.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Record {
    /// Where the samples came from (a file path or a label), for messages.
    pub source: String,
    /// The samples, in time order.
    pub samples: Vec<Sample>,
    /// The 1-based line of each sample in the source (for messages).
    pub lines: Vec<u64>,
}

impl Record {
    /// A record of generated samples (lines numbered as if from a file with
    /// a header line).
    pub fn from_samples(source: impl Into<String>, samples: Vec<Sample>) -> Record {
        let lines = (0..samples.len() as u64).map(|i| i + 2).collect();
        Record {
            source: source.into(),
            samples,
            lines,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Line of sample `i` in the source.
    pub fn line(&self, i: usize) -> u64 {
        self.lines.get(i).copied().unwrap_or(0)
    }
}

/// What is wrong with an input.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum DataErrorKind {
    /// The file could not be read.
    Io(String),
    /// The file has no header line.
    NoHeader,
    /// A required column is not in the header.
    MissingColumn,
    /// A row has fewer fields than the column needs.
    MissingField,
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
    /// The file has a header but no samples.
    NoSamples,
    /// Too few samples to identify the model; the text says which group.
    TooFewSamples(String),
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
        match &self.kind {
            DataErrorKind::Io(e) => write!(f, "cannot read: {e}"),
            DataErrorKind::NoHeader => {
                write!(f, "no header line (expected `{}`)", COLUMNS.join(","))
            }
            DataErrorKind::MissingColumn => {
                write!(f, "missing from the header (need `{}`)", COLUMNS.join(","))
            }
            DataErrorKind::MissingField => write!(f, "row has no field for this column"),
            DataErrorKind::NotANumber(s) => write!(f, "`{s}` is not a number"),
            DataErrorKind::NonFinite => write!(f, "value is NaN or infinite"),
            DataErrorKind::TimeBackwards { previous_s, t_s } => write!(
                f,
                "time goes backwards ({t_s} s after {previous_s} s on the previous sample)"
            ),
            DataErrorKind::Impossible { value, allowed } => {
                write!(f, "physically impossible value {value} ({allowed})")
            }
            DataErrorKind::NoSamples => write!(f, "no samples after the header"),
            DataErrorKind::TooFewSamples(what) => {
                write!(f, "too few samples to identify the model: {what}")
            }
        }
    }
}

impl std::error::Error for DataError {}

/// Read and validate a measurement file.
pub fn read_csv(path: &Path) -> Result<Record, DataError> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|e| DataError {
        file: name.clone(),
        line: 0,
        column: None,
        kind: DataErrorKind::Io(e.to_string()),
    })?;
    parse_csv(&name, std::io::BufReader::with_capacity(1 << 16, file))
}

/// Parse and validate CSV text from `reader`; `source` names it in errors.
///
/// Fields are separated by commas and trimmed; a field may be wrapped in
/// double quotes (quoted commas are not supported: measurement files have
/// none). Lines are counted as an editor counts them, comments included.
pub fn parse_csv<R: Read>(source: &str, mut reader: R) -> Result<Record, DataError> {
    let err = |line: u64, column: Option<&str>, kind| DataError {
        file: source.to_string(),
        line,
        column: column.map(str::to_string),
        kind,
    };
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|e| err(0, None, DataErrorKind::Io(e.to_string())))?;
    let mut lines = bytes
        .split(|&b| b == b'\n')
        .enumerate()
        .map(|(i, l)| (i as u64 + 1, l.strip_suffix(b"\r").unwrap_or(l)))
        .filter(|(_, l)| {
            let t = l.trim_ascii();
            !t.is_empty() && !t.starts_with(b"#")
        });

    let (header_line, header) = lines
        .next()
        .ok_or_else(|| err(0, None, DataErrorKind::NoHeader))?;
    let header: Vec<&[u8]> = header.split(|&b| b == b',').map(field_text).collect();
    let mut idx = [0usize; 4];
    for (k, name) in COLUMNS.iter().enumerate() {
        idx[k] = header
            .iter()
            .position(|h| *h == name.as_bytes())
            .ok_or_else(|| err(header_line, Some(name), DataErrorKind::MissingColumn))?;
    }
    let needed = idx.iter().copied().max().unwrap_or(0) + 1;

    let mut samples = Vec::new();
    let mut line_numbers = Vec::new();
    let mut fields: Vec<&[u8]> = Vec::with_capacity(header.len());
    let mut previous_t: Option<f64> = None;
    for (line, text) in lines {
        fields.clear();
        fields.extend(text.split(|&b| b == b',').take(needed).map(field_text));
        let mut v = [0f64; 4];
        for k in 0..4 {
            let name = COLUMNS[k];
            let field = match fields.get(idx[k]) {
                Some(f) if !f.is_empty() => *f,
                _ => return Err(err(line, Some(name), DataErrorKind::MissingField)),
            };
            let x: f64 = std::str::from_utf8(field)
                .ok()
                .and_then(|t| t.parse().ok())
                .ok_or_else(|| {
                    err(
                        line,
                        Some(name),
                        DataErrorKind::NotANumber(String::from_utf8_lossy(field).into_owned()),
                    )
                })?;
            if !x.is_finite() {
                return Err(err(line, Some(name), DataErrorKind::NonFinite));
            }
            v[k] = x;
        }
        let s = Sample {
            t_s: v[0],
            load_n: v[1],
            pressure_mpa: v[2],
            contraction: v[3],
        };
        if let Some(prev) = previous_t {
            if s.t_s < prev {
                return Err(err(
                    line,
                    Some("t_s"),
                    DataErrorKind::TimeBackwards {
                        previous_s: prev,
                        t_s: s.t_s,
                    },
                ));
            }
        }
        previous_t = Some(s.t_s);
        check_physical(&s).map_err(|(col, value, allowed)| {
            err(
                line,
                Some(col),
                DataErrorKind::Impossible { value, allowed },
            )
        })?;
        samples.push(s);
        line_numbers.push(line);
    }
    if samples.is_empty() {
        return Err(err(0, None, DataErrorKind::NoSamples));
    }
    Ok(Record {
        source: source.to_string(),
        samples,
        lines: line_numbers,
    })
}

/// A field without surrounding blanks and double quotes.
fn field_text(f: &[u8]) -> &[u8] {
    let f = f.trim_ascii();
    f.strip_prefix(b"\"")
        .and_then(|g| g.strip_suffix(b"\""))
        .map_or(f, <[u8]>::trim_ascii)
}

/// The physical limits every sample must meet: `(column, value, allowed)` of
/// the first violation.
pub fn check_physical(s: &Sample) -> Result<(), (&'static str, f64, &'static str)> {
    if !(s.load_n >= 0.0 && s.load_n <= MAX_LOAD_N) {
        return Err((
            "load_n",
            s.load_n,
            "a muscle only pulls: 0 <= load_n <= 100000 N",
        ));
    }
    if !(s.pressure_mpa >= MIN_PRESSURE_MPA && s.pressure_mpa <= MAX_PRESSURE_MPA) {
        return Err((
            "pressure_mpa",
            s.pressure_mpa,
            "gauge pressure between vacuum (-0.101325 MPa) and 10 MPa",
        ));
    }
    if !(s.contraction > -1.0 && s.contraction < 1.0) {
        return Err((
            "contraction",
            s.contraction,
            "a fraction of rest length strictly between -1 and 1",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Record, DataError> {
        parse_csv("test.csv", text.as_bytes())
    }

    #[test]
    fn reads_columns_in_any_order_with_extras_and_comments() {
        let r = parse(
            "# rig 7\nextra,contraction,t_s,pressure_mpa,load_n\n\
             a,0.02,0.0,0.001,100\n# pause\n\nb,0.03,0.02,0.01,100.5\n",
        )
        .unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(
            r.samples[1],
            Sample {
                t_s: 0.02,
                load_n: 100.5,
                pressure_mpa: 0.01,
                contraction: 0.03
            }
        );
        assert_eq!(r.lines, vec![3, 6]);
    }

    #[test]
    fn missing_column_names_the_column_and_the_header_line() {
        let e = parse("t_s,load_n,contraction\n0,100,0.02\n").unwrap_err();
        assert_eq!(e.kind, DataErrorKind::MissingColumn);
        assert_eq!(e.column.as_deref(), Some("pressure_mpa"));
        assert_eq!(e.line, 1);
        assert_eq!(
            e.to_string(),
            "test.csv:1: column `pressure_mpa`: missing from the header (need `t_s,load_n,pressure_mpa,contraction`)"
        );
    }

    #[test]
    fn non_numeric_field_is_located() {
        let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.02\n0.02,100,0.1x,0.02\n")
            .unwrap_err();
        assert_eq!(e.line, 3);
        assert_eq!(e.column.as_deref(), Some("pressure_mpa"));
        assert_eq!(e.kind, DataErrorKind::NotANumber("0.1x".into()));
    }

    #[test]
    fn nan_and_infinity_are_refused() {
        for bad in ["NaN", "inf", "-inf"] {
            let e = parse(&format!(
                "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,{bad}\n"
            ))
            .unwrap_err();
            assert_eq!(e.kind, DataErrorKind::NonFinite, "{bad}");
            assert_eq!((e.line, e.column.as_deref()), (2, Some("contraction")));
        }
    }

    #[test]
    fn short_row_is_a_missing_field() {
        let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,0.1\n").unwrap_err();
        assert_eq!(e.kind, DataErrorKind::MissingField);
        assert_eq!(e.column.as_deref(), Some("contraction"));
    }

    #[test]
    fn time_going_backwards_is_refused_but_repeats_are_not() {
        let ok = "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.02\n0,100,0.1,0.02\n";
        assert!(parse(ok).is_ok());
        let e = parse("t_s,load_n,pressure_mpa,contraction\n1,100,0.1,0.02\n0.5,100,0.1,0.02\n")
            .unwrap_err();
        assert_eq!((e.line, e.column.as_deref()), (3, Some("t_s")));
        assert!(matches!(e.kind, DataErrorKind::TimeBackwards { .. }));
    }

    #[test]
    fn impossible_values_are_refused() {
        for (row, col) in [
            ("0,-5,0.1,0.02", "load_n"),
            ("0,100,-0.5,0.02", "pressure_mpa"),
            ("0,100,11,0.02", "pressure_mpa"),
            ("0,100,0.1,1.2", "contraction"),
        ] {
            let e = parse(&format!("t_s,load_n,pressure_mpa,contraction\n{row}\n")).unwrap_err();
            assert_eq!(e.column.as_deref(), Some(col), "{row}");
            assert!(matches!(e.kind, DataErrorKind::Impossible { .. }));
        }
    }

    #[test]
    fn empty_inputs_are_refused() {
        assert_eq!(parse("").unwrap_err().kind, DataErrorKind::NoHeader);
        assert_eq!(
            parse("t_s,load_n,pressure_mpa,contraction\n# nothing\n")
                .unwrap_err()
                .kind,
            DataErrorKind::NoSamples
        );
    }

    #[test]
    fn unreadable_file_is_named() {
        let e = read_csv(Path::new("/nonexistent/x.csv")).unwrap_err();
        assert!(e.to_string().starts_with("/nonexistent/x.csv: cannot read"));
    }
}
