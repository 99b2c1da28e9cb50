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

pub mod import;
pub mod split;

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

/// Most samples a record may have (a 2-hour test at 100 Hz is 720 000).
/// Longer records are refused, not read into memory without bound:
/// decimate them first.
pub const MAX_ROWS: usize = 1_000_000;
/// Most bytes a record file may have, 64 MiB.
pub const MAX_BYTES: u64 = 64 << 20;

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

/// Header names that carry a wrong unit, and what to do.
const WRONG_UNITS: [(&str, &str); 14] = [
    (
        "pressure_kpa",
        "pressure must be in MPa (`pressure_mpa`): divide by 1000",
    ),
    (
        "pressure_bar",
        "pressure must be in MPa (`pressure_mpa`): divide by 10",
    ),
    (
        "pressure_psi",
        "pressure must be in MPa (`pressure_mpa`): multiply by 0.006895",
    ),
    (
        "pressure_pa",
        "pressure must be in MPa (`pressure_mpa`): divide by 1e6",
    ),
    (
        "pressure",
        "name the pressure column `pressure_mpa`, in MPa",
    ),
    (
        "contraction_pct",
        "contraction must be a fraction of rest length: divide by 100",
    ),
    (
        "contraction_percent",
        "contraction must be a fraction of rest length: divide by 100",
    ),
    (
        "contraction_%",
        "contraction must be a fraction of rest length: divide by 100",
    ),
    (
        "contraction_mm",
        "contraction must be a fraction of rest length: divide by the rest length",
    ),
    (
        "load_kg",
        "load must be in newtons (`load_n`): multiply by 9.81",
    ),
    ("load", "name the load column `load_n`, in newtons"),
    ("t_ms", "time must be in seconds (`t_s`): divide by 1000"),
    ("time", "name the time column `t_s`, in seconds"),
    ("t", "name the time column `t_s`, in seconds"),
];

/// Read and validate a measurement file (at most [`MAX_BYTES`] and
/// [`MAX_ROWS`]).
pub fn read_csv(path: &Path) -> Result<Record, DataError> {
    let name = path.display().to_string();
    let io = |e: std::io::Error| DataError {
        file: name.clone(),
        line: 0,
        column: None,
        kind: DataErrorKind::Io(e.to_string()),
    };
    let file = std::fs::File::open(path).map_err(io)?;
    if file.metadata().map_err(io)?.is_dir() {
        return Err(io(std::io::Error::other("is a directory")));
    }
    parse_csv(&name, file)
}

/// Byte offsets of the line ends (`\n`, and `\r`) read so far and not yet
/// passed, and how many lines were passed: the line of a record from its
/// byte offset, as an editor counts lines. (The `csv` crate's own line
/// count skips blank lines, and its record offset can point at the blank
/// lines before the record.)
#[derive(Default)]
struct Lines {
    /// `(offset, is '\n')`.
    pending: std::collections::VecDeque<(u64, bool)>,
    passed: u64,
}

impl Lines {
    /// 1-based line of the record reported at `offset`. Offsets must not
    /// decrease between calls (records are read in order).
    fn line_of(&mut self, mut offset: u64) -> u64 {
        while let Some(&(at, lf)) = self.pending.front() {
            if at < offset {
                self.passed += u64::from(lf);
            } else if at == offset {
                // The record starts after the line ends at its offset.
                self.passed += u64::from(lf);
                offset += 1;
            } else {
                break;
            }
            self.pending.pop_front();
        }
        self.passed + 1
    }
}

/// A reader that stops with an error past [`MAX_BYTES`], remembers whether
/// it did, and notes where the newlines are.
struct Bounded<R> {
    inner: R,
    read: u64,
    over: std::rc::Rc<std::cell::Cell<bool>>,
    lines: std::rc::Rc<std::cell::RefCell<Lines>>,
}

impl<R: Read> Read for Bounded<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.read >= MAX_BYTES {
            // One byte more tells a file of exactly MAX_BYTES from a longer one.
            let mut one = [0u8; 1];
            if self.inner.read(&mut one)? > 0 {
                self.over.set(true);
                return Err(std::io::Error::other("too large"));
            }
            return Ok(0);
        }
        let room = (MAX_BYTES - self.read).min(buf.len() as u64) as usize;
        let n = self.inner.read(&mut buf[..room])?;
        let mut lines = self.lines.borrow_mut();
        for (i, b) in buf[..n].iter().enumerate() {
            if *b == b'\n' || *b == b'\r' {
                lines.pending.push_back((self.read + i as u64, *b == b'\n'));
            }
        }
        self.read += n as u64;
        Ok(n)
    }
}

/// Parse and validate CSV text from `reader`; `source` names it in errors.
///
/// The [`csv`] crate splits the fields (double quotes, CRLF line ends); a
/// UTF-8 byte-order mark is skipped; fields are trimmed; lines starting with
/// `#` and blank lines are skipped. Lines are counted as an editor counts
/// them, comments included. Reading stops with an error past [`MAX_BYTES`]
/// or [`MAX_ROWS`], and at once on a byte that is not text (a NUL byte or
/// invalid UTF-8), so an endless or binary input is refused, not read into
/// memory.
pub fn parse_csv<R: Read>(source: &str, reader: R) -> Result<Record, DataError> {
    let err = |line: u64, column: Option<&str>, kind| DataError {
        file: source.to_string(),
        line,
        column: column.map(str::to_string),
        kind,
    };
    // Look at the start: a BOM, a binary file.
    let over = std::rc::Rc::new(std::cell::Cell::new(false));
    let lines = std::rc::Rc::new(std::cell::RefCell::new(Lines::default()));
    let mut bounded = Bounded {
        inner: reader,
        read: 0,
        over: over.clone(),
        lines: lines.clone(),
    };
    let mut head = Vec::with_capacity(4096);
    (&mut bounded)
        .take(4096)
        .read_to_end(&mut head)
        .map_err(|e| err(0, None, DataErrorKind::Io(e.to_string())))?;
    let mut skip = 0;
    if head.starts_with(b"\xEF\xBB\xBF") {
        skip = 3;
    }
    check_text(&head[skip..], skip as u64, head.len() == 4096)
        .map_err(|offset| err(0, None, DataErrorKind::Binary { offset }))?;
    let start = std::io::Cursor::new(head.split_off(skip)).chain(bounded);
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(start);
    let mut row = csv::ByteRecord::new();
    // The next row that is not a comment (`#` first) nor blank.
    let read_row = |rdr: &mut csv::Reader<_>, row: &mut csv::ByteRecord, line: u64| loop {
        let more = rdr.read_byte_record(row).map_err(|e| {
            if over.get() {
                return err(0, None, DataErrorKind::TooLarge);
            }
            let line = e.position().map_or(line, |p| p.line());
            err(line, None, DataErrorKind::Io(e.to_string()))
        })?;
        if !more {
            return Ok(false);
        }
        let first = row.get(0).unwrap_or_default();
        let blank = row.len() == 1 && first.is_empty();
        if !blank && !first.starts_with(b"#") {
            return Ok(true);
        }
    };

    // Header.
    if !read_row(&mut rdr, &mut row, 0)? {
        return Err(err(0, None, DataErrorKind::NoHeader));
    }
    // The csv reader's byte offsets start after a skipped byte-order mark.
    let line_at = |row: &csv::ByteRecord| {
        row.position()
            .map_or(0, |p| lines.borrow_mut().line_of(p.byte() + skip as u64))
    };
    let header_line = line_at(&row);
    let header: Vec<String> = row
        .iter()
        .map(|h| String::from_utf8_lossy(h).trim().to_string())
        .collect();
    check_header(&header).map_err(|(col, kind)| err(header_line, col.as_deref(), kind))?;
    let mut idx = [0usize; 4];
    for (k, name) in COLUMNS.iter().enumerate() {
        idx[k] = header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| err(header_line, Some(name), DataErrorKind::MissingColumn))?;
    }

    let mut samples = Vec::new();
    let mut line_numbers = Vec::new();
    let mut previous_t: Option<f64> = None;
    let mut last_line = header_line;
    while read_row(&mut rdr, &mut row, last_line)? {
        let line = line_at(&row);
        last_line = line;
        if samples.len() >= MAX_ROWS {
            return Err(err(line, None, DataErrorKind::TooManyRows));
        }
        if row.len() > header.len() {
            return Err(err(
                line,
                None,
                DataErrorKind::ExtraFields {
                    fields: row.len(),
                    header: header.len(),
                },
            ));
        }
        let mut v = [0f64; 4];
        for k in 0..4 {
            let name = COLUMNS[k];
            let field = match row.get(idx[k]) {
                Some(f) if !f.is_empty() => f,
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
            let kind = match likely_unit(col, value) {
                Some(hint) => DataErrorKind::LikelyUnit { value, hint },
                None => DataErrorKind::Impossible { value, allowed },
            };
            err(line, Some(col), kind)
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

/// `Err(offset)` of the first byte that is not text: NUL, or invalid UTF-8
/// (a sequence cut by the end of a `truncated` chunk is fine).
fn check_text(bytes: &[u8], base: u64, truncated: bool) -> Result<(), u64> {
    let nul = bytes.iter().position(|&b| b == 0);
    let utf8 = match std::str::from_utf8(bytes) {
        Ok(_) => None,
        Err(e) if truncated && e.error_len().is_none() => None,
        Err(e) => Some(e.valid_up_to()),
    };
    match (nul, utf8) {
        (None, None) => Ok(()),
        (a, b) => Err(base + a.unwrap_or(usize::MAX).min(b.unwrap_or(usize::MAX)) as u64),
    }
}

/// The header's defects that have a reason of their own.
fn check_header(header: &[String]) -> Result<(), (Option<String>, DataErrorKind)> {
    if header.len() == 1 {
        let h = &header[0];
        for sep in [';', '\t', '|', ' '] {
            if COLUMNS.iter().filter(|c| h.contains(*c)).count() >= 2 && h.contains(sep) {
                return Err((None, DataErrorKind::WrongSeparator(sep)));
            }
        }
    }
    if !header.is_empty()
        && header
            .iter()
            .all(|h| !h.is_empty() && h.parse::<f64>().is_ok())
    {
        return Err((None, DataErrorKind::HeaderIsData));
    }
    for (i, h) in header.iter().enumerate() {
        if COLUMNS.contains(&h.as_str()) && header[..i].contains(h) {
            return Err((Some(h.clone()), DataErrorKind::DuplicateColumn));
        }
    }
    for c in COLUMNS {
        if header.iter().any(|h| h == c) {
            continue;
        }
        for h in header {
            let low = h.to_ascii_lowercase();
            if let Some((_, hint)) = WRONG_UNITS
                .iter()
                .find(|(n, _)| *n == low && n.split('_').next() == c.split('_').next())
            {
                return Err((
                    Some(c.to_string()),
                    DataErrorKind::WrongUnit {
                        found: h.clone(),
                        hint,
                    },
                ));
            }
        }
    }
    Ok(())
}

/// The unit an out-of-range value looks like it is in.
fn likely_unit(column: &str, value: f64) -> Option<&'static str> {
    match column {
        "pressure_mpa" if value > MAX_PRESSURE_MPA && value <= 10_000.0 => {
            Some("pressure_mpa is in MPa; this looks like kPa (divide by 1000)")
        }
        "contraction" if (1.0..=100.0).contains(&value) => Some(
            "contraction is a fraction of rest length; this looks like per cent (divide by 100)",
        ),
        _ => None,
    }
}

/// What a command needs of a record beyond valid samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// Identify the model (`fit`): pressure and contraction must vary, and
    /// two loads are checked by the fit itself.
    Fit,
    /// Diagnose: as [`Purpose::Fit`], and at least [`DIAGNOSE_MIN_SAMPLES`].
    Diagnose,
    /// Drive a model (`simulate`): the pressure must vary.
    Simulate,
}

/// One channel of a sample.
type Channel = fn(&Sample) -> f64;

/// Fewest samples `diagnose` works on.
pub const DIAGNOSE_MIN_SAMPLES: usize = 100;

/// Record-level checks, before any work: time advances, the channels the
/// command needs vary, no sensor is stuck for a long stretch while the
/// others move (at least 200 samples and a tenth of the record).
pub fn check_record(record: &Record, purpose: Purpose) -> Result<(), DataError> {
    let s = &record.samples;
    let err = |line: u64, column: Option<&str>, kind| DataError {
        file: record.source.clone(),
        line,
        column: column.map(str::to_string),
        kind,
    };
    let (Some(first), Some(last)) = (s.first(), s.last()) else {
        return Err(err(0, None, DataErrorKind::NoSamples));
    };
    if s.len() > 1 && last.t_s <= first.t_s {
        return Err(err(0, Some("t_s"), DataErrorKind::TimeNeverAdvances));
    }
    if purpose == Purpose::Diagnose && s.len() < DIAGNOSE_MIN_SAMPLES {
        return Err(err(
            0,
            None,
            DataErrorKind::TooFewSamples(format!(
                "{} samples, diagnose needs at least {DIAGNOSE_MIN_SAMPLES}",
                s.len()
            )),
        ));
    }
    let constant = |f: fn(&Sample) -> f64| s.iter().all(|x| f(x) == f(first));
    let mut need: Vec<(&str, Channel)> = vec![("pressure_mpa", |x| x.pressure_mpa)];
    if purpose != Purpose::Simulate {
        need.push(("contraction", |x| x.contraction));
    }
    for (name, f) in need {
        if s.len() > 1 && constant(f) {
            return Err(err(
                0,
                Some(name),
                DataErrorKind::Constant { value: f(first) },
            ));
        }
    }
    // A stuck sensor: one exact value for a long run while another channel
    // moves. (Quantised readings repeat on holds, but then nothing moves.)
    let min_run = (s.len() / 10).max(200);
    let channels: [(&str, Channel, Channel, &str, f64); 2] = [
        (
            "contraction",
            |x| x.contraction,
            |x| x.pressure_mpa,
            "MPa of pressure",
            0.05,
        ),
        (
            "pressure_mpa",
            |x| x.pressure_mpa,
            |x| x.contraction,
            "of contraction",
            0.02,
        ),
    ];
    // A record whose contraction is held at two or more exact values
    // throughout (each for at least 200 samples) is an isometric protocol whose
    // lengths were set, not measured (`pam-lab import` writes held lengths
    // so): nothing there can be a stuck length sensor.
    let held_protocol = {
        let (mut runs_ok, mut runs) = (true, 0);
        let mut start = 0;
        for i in 1..=s.len() {
            if i < s.len() && s[i].contraction == s[start].contraction {
                continue;
            }
            runs_ok &= i - start >= 200;
            runs += 1;
            start = i;
        }
        runs_ok && runs >= 2
    };
    for (name, f, other, what, threshold) in channels {
        if name == "contraction" && held_protocol {
            continue;
        }
        let mut start = 0;
        for i in 1..=s.len() {
            if i < s.len() && f(&s[i]) == f(&s[start]) {
                continue;
            }
            let n = i - start;
            if n >= min_run {
                let (lo, hi) = s[start..i]
                    .iter()
                    .map(other)
                    .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
                if hi - lo >= threshold && !(name == "contraction" && held_length(&s[start..i])) {
                    return Err(err(
                        record.line(start),
                        Some(name),
                        DataErrorKind::Stuck {
                            value: f(&s[start]),
                            until_line: record.line(i - 1),
                            samples: n,
                            fraction: n as f64 / s.len() as f64,
                            moved: format!("{:.3} {what} moved", hi - lo),
                        },
                    ));
                }
            }
            start = i;
        }
    }
    Ok(())
}

/// Highest pressure a pneumatic muscle is commonly run at, MPa (Festo's
/// are rated to 0.8 MPa): a record above it is more likely in bar.
pub const PNEUMATIC_TOP_MPA: f64 = 1.0;

/// Units a record's values suggest were not the format's, said as
/// warnings (the values are possible, so not refused): a pressure whose
/// top (99th percentile) is above [`PNEUMATIC_TOP_MPA`] (bar for MPa), a time step of a
/// second or more over a record of hours (milliseconds for seconds: a rig
/// that shows a hysteresis loop samples far faster).
pub fn unit_warnings(record: &Record) -> Vec<String> {
    let s = &record.samples;
    let mut out = Vec::new();
    if s.len() < 3 {
        return out;
    }
    let mut p: Vec<f64> = s.iter().map(|x| x.pressure_mpa).collect();
    p.sort_by(f64::total_cmp);
    let p99 = p[(p.len() - 1) * 99 / 100];
    if p99 > PNEUMATIC_TOP_MPA {
        out.push(format!(
            "{}: column `pressure_mpa` reaches {} MPa: a pneumatic muscle works below about {} \
             MPa; if the column is in bar, divide it by 10 (a hydraulic muscle: ignore this)",
            record.source,
            num(p99),
            PNEUMATIC_TOP_MPA
        ));
    }
    let mut dt: Vec<f64> = s.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    dt.sort_by(f64::total_cmp);
    let median_dt = dt[dt.len() / 2];
    let hours = (s[s.len() - 1].t_s - s[0].t_s) / 3600.0;
    if median_dt >= 1.0 && hours >= 5.0 {
        out.push(format!(
            "{}: column `t_s` steps {} s per sample over {:.1} h: if the column is in \
             milliseconds, divide it by 1000 (the effects' time constants depend on it)",
            record.source,
            num(median_dt),
            hours
        ));
    }
    out
}

/// Whether a stretch of constant contraction while the pressure moves is
/// an isometric hold, not a stuck sensor: at a held length the muscle
/// answers the pressure with force, so the load moves well above its noise
/// (5×) and in step with the pressure (correlation at least 0.5). A stuck
/// contraction sensor on an isotonic rig shows a hung load that does not
/// follow the pressure.
fn held_length(run: &[Sample]) -> bool {
    if run.len() < 3 {
        return false;
    }
    let load_noise = noise_std(run.iter().map(|s| s.load_n));
    let (lo, hi) = run.iter().fold((f64::MAX, f64::MIN), |(a, b), s| {
        (a.min(s.load_n), b.max(s.load_n))
    });
    if !(hi - lo > 5.0 * load_noise && hi > lo) {
        return false;
    }
    correlation(run, |s| s.pressure_mpa, |s| s.load_n) >= 0.5
}

/// Pearson correlation of two channels over a record (0 when one holds).
pub fn correlation(samples: &[Sample], f: fn(&Sample) -> f64, g: fn(&Sample) -> f64) -> f64 {
    let n = samples.len().max(1) as f64;
    let (mf, mg) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), s| (a + f(s) / n, b + g(s) / n));
    let (mut sfg, mut sff, mut sgg) = (0.0, 0.0, 0.0);
    for s in samples {
        let (df, dg) = (f(s) - mf, g(s) - mg);
        sfg += df * dg;
        sff += df * df;
        sgg += dg * dg;
    }
    if sff > 0.0 && sgg > 0.0 {
        sfg / (sff * sgg).sqrt()
    } else {
        0.0
    }
}

/// Robust standard deviation of white noise on a smooth signal, from the
/// median absolute second difference: `var(x[i+1] − 2x[i] + x[i−1]) = 6σ²`,
/// and `σ ≈ 1.4826 · MAD` for Gaussian noise.
pub fn noise_std(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let v: Vec<f64> = values.collect();
    if v.len() < 3 {
        return 0.0;
    }
    let mut d2: Vec<f64> = v
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    let mid = d2.len() / 2;
    let (_, m, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *m / 6f64.sqrt()
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
            ("0,100,20000,0.02", "pressure_mpa"),
            ("0,100,0.1,120", "contraction"),
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

    #[test]
    fn lines_are_counted_as_an_editor_counts_them() {
        let text = "# a\r\n\r\nt_s,load_n,pressure_mpa,contraction\r\n\r\n\n# b\n1,100,0.1,0.02\n\n\n2,100,0.1,0.02\r\n";
        assert_eq!(parse(text).unwrap().lines, vec![7, 10]);
        let e = parse("\n\n# x\n\nt_s,load_n,pressure_mpa\n").unwrap_err();
        assert_eq!(e.line, 5);
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let r = parse("\u{feff}t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.02\n").unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r.lines, vec![2]);
    }

    #[test]
    fn separators_other_than_commas_are_named() {
        for (sep, shown) in [(";", "`;`"), ("\t", "`\\t`"), ("|", "`|`")] {
            let text = format!(
                "t_s{sep}load_n{sep}pressure_mpa{sep}contraction\n0{sep}100{sep}0.1{sep}0.02\n"
            );
            let e = parse(&text).unwrap_err();
            assert_eq!(
                e.kind,
                DataErrorKind::WrongSeparator(sep.chars().next().unwrap())
            );
            assert!(e.to_string().contains(shown), "{e}");
        }
    }

    #[test]
    fn binary_input_is_refused_at_its_first_bad_byte() {
        let e = parse_csv("x.bin", &b"t_s,load\x00_n"[..]).unwrap_err();
        assert_eq!(e.kind, DataErrorKind::Binary { offset: 8 });
        let e = parse_csv("x.bin", &b"\xff\xfe\x00t"[..]).unwrap_err();
        assert_eq!(e.kind, DataErrorKind::Binary { offset: 0 });
    }

    #[test]
    fn an_endless_input_stops_at_the_byte_limit() {
        // A header, then one comment line that never ends.
        let endless = std::io::Read::chain(
            &b"t_s,load_n,pressure_mpa,contraction\n#"[..],
            std::io::repeat(b'x'),
        );
        let e = parse_csv("endless", endless).unwrap_err();
        assert_eq!(e.kind, DataErrorKind::TooLarge);
    }

    #[test]
    fn units_are_recognised_in_the_header_and_in_values() {
        let e = parse("t_s,load_n,pressure_bar,contraction\n0,100,1,0.02\n").unwrap_err();
        assert!(matches!(e.kind, DataErrorKind::WrongUnit { .. }), "{e}");
        assert_eq!(e.column.as_deref(), Some("pressure_mpa"));
        let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,250,0.02\n").unwrap_err();
        assert!(e.to_string().contains("looks like kPa"), "{e}");
        let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,0.1,15\n").unwrap_err();
        assert!(e.to_string().contains("looks like per cent"), "{e}");
        // Beyond any unit: plain impossible.
        let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,20000,0.02\n").unwrap_err();
        assert!(matches!(e.kind, DataErrorKind::Impossible { .. }), "{e}");
    }

    #[test]
    fn numbers_are_printed_short() {
        assert_eq!(num(1e30), "1e30");
        assert_eq!(num(-2.5e-7), "-2.5e-7");
        assert_eq!(num(0.25), "0.25");
        assert_eq!(num(0.0), "0");
        assert_eq!(num32(0.498_863_34), "0.49886334");
    }

    fn record(f: impl Fn(usize) -> Sample, n: usize) -> Record {
        Record::from_samples("r.csv", (0..n).map(f).collect())
    }

    fn ramp(i: usize) -> Sample {
        let u = (i % 200) as f64 / 200.0;
        Sample {
            t_s: i as f64 * 0.02,
            load_n: 100.0,
            pressure_mpa: 0.5 * u,
            contraction: 0.02 + 0.2 * u,
        }
    }

    #[test]
    fn record_checks_find_time_constant_and_stuck_channels() {
        assert!(check_record(&record(ramp, 3000), Purpose::Fit).is_ok());
        let e = check_record(
            &record(
                |i| Sample {
                    t_s: 0.0,
                    ..ramp(i)
                },
                3000,
            ),
            Purpose::Simulate,
        )
        .unwrap_err();
        assert_eq!(e.kind, DataErrorKind::TimeNeverAdvances);
        let e = check_record(
            &record(
                |i| Sample {
                    contraction: 0.1,
                    ..ramp(i)
                },
                3000,
            ),
            Purpose::Fit,
        )
        .unwrap_err();
        assert_eq!(e.kind, DataErrorKind::Constant { value: 0.1 });
        // Simulate needs no varying contraction, but a stuck sensor is one.
        let e = check_record(
            &record(
                |i| Sample {
                    contraction: 0.1,
                    ..ramp(i)
                },
                3000,
            ),
            Purpose::Simulate,
        )
        .unwrap_err();
        assert!(matches!(e.kind, DataErrorKind::Stuck { .. }), "{e}");
        let stuck = record(
            |i| {
                let mut s = ramp(i);
                if (1000..2000).contains(&i) {
                    s.contraction = 0.07;
                }
                s
            },
            3000,
        );
        let e = check_record(&stuck, Purpose::Fit).unwrap_err();
        assert_eq!((e.line, e.column.as_deref()), (1002, Some("contraction")));
        assert!(
            matches!(
                e.kind,
                DataErrorKind::Stuck {
                    samples: 1000,
                    until_line: 2001,
                    ..
                }
            ),
            "{e}"
        );
        // A hold (nothing moves) is no fault.
        let hold = record(
            |i| {
                if (1000..2000).contains(&i) {
                    Sample {
                        t_s: i as f64 * 0.02,
                        ..ramp(999)
                    }
                } else {
                    ramp(i)
                }
            },
            3000,
        );
        assert!(check_record(&hold, Purpose::Fit).is_ok());
        let e = check_record(&record(ramp, 60), Purpose::Diagnose).unwrap_err();
        assert!(matches!(e.kind, DataErrorKind::TooFewSamples(_)));
    }

    #[test]
    fn a_held_length_is_the_protocol_not_a_stuck_sensor() {
        // Held at exact lengths throughout (an imported isometric test):
        // the protocol, whatever the load does.
        let held = record(
            |i| Sample {
                contraction: if i < 1500 { 0.0 } else { 0.04 },
                ..ramp(i)
            },
            3000,
        );
        assert!(check_record(&held, Purpose::Fit).is_ok());
        // One stretch held while the force follows the pressure: a hold.
        let answered = |load: fn(&Sample) -> f64| {
            record(
                move |i| {
                    let mut s = ramp(i);
                    if (1000..2000).contains(&i) {
                        s.contraction = 0.07;
                        s.load_n = load(&s);
                    }
                    s
                },
                3000,
            )
        };
        let force = answered(|s| 50.0 + 400.0 * s.pressure_mpa);
        assert!(check_record(&force, Purpose::Fit).is_ok());
        // A hung load that does not answer: a stuck sensor.
        let hung = answered(|s| s.load_n);
        let e = check_record(&hung, Purpose::Fit).unwrap_err();
        assert!(matches!(e.kind, DataErrorKind::Stuck { .. }), "{e}");
    }
}
