//! The CSV reader: bounded input, located errors, units guessed from
//! values that cannot be in pam's.

use std::io::Read;
use std::path::Path;

use super::*;

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
    // The next row that is not a comment (`#` first) nor blank; a `#
    // segment: LABEL` comment on the way leaves its label in `seam`.
    let read_row = |rdr: &mut csv::Reader<_>,
                    row: &mut csv::ByteRecord,
                    line: u64,
                    seam: &mut Option<String>| loop {
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
        // The comment's fields, trimmed by the reader, joined as a list.
        let comment: Vec<_> = row.iter().map(String::from_utf8_lossy).collect();
        if let Some(label) = comment.join(", ").strip_prefix('#').and_then(|c| {
            c.trim_start()
                .strip_prefix(SEGMENT_COMMENT)
                .map(|l| l.trim().to_string())
        }) {
            *seam = Some(label);
        }
    };

    // Header.
    let mut seam = None;
    if !read_row(&mut rdr, &mut row, 0, &mut seam)? {
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
    let mut segments = Vec::new();
    let mut previous_t: Option<f64> = None;
    let mut last_line = header_line;
    while read_row(&mut rdr, &mut row, last_line, &mut seam)? {
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
        if let Some(label) = seam.take() {
            segments.push(Segment {
                start: samples.len(),
                label,
            });
        }
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
        segments,
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

/// Largest pressure value that may be in psi rather than kPa: 150 psi is
/// 1.03 MPa, above a pneumatic muscle's range (a McKibben muscle's 0.6 MPa
/// is 87 psi), while 150 kPa is a muscle barely inflated.
const PSI_OR_KPA_UP_TO: f64 = 150.0;

/// The unit an out-of-range value looks like it is in.
///
/// A pressure above [`MAX_PRESSURE_MPA`] up to [`PSI_OR_KPA_UP_TO`] may be
/// psi or kPa (the first value of a ramp past the limit is near it in
/// either), so both are named with their factors; above it, kPa.
fn likely_unit(column: &str, value: f64) -> Option<&'static str> {
    match column {
        "pressure_mpa" if value > MAX_PRESSURE_MPA && value <= PSI_OR_KPA_UP_TO => Some(
            "pressure_mpa is in MPa; this looks like kPa (divide by 1000) or psi (multiply by 0.006895)",
        ),
        "pressure_mpa" if value > PSI_OR_KPA_UP_TO && value <= 10_000.0 => {
            Some("pressure_mpa is in MPa; this looks like kPa (divide by 1000)")
        }
        "contraction" if (1.0..=100.0).contains(&value) => Some(
            "contraction is a fraction of rest length; this looks like per cent (divide by 100)",
        ),
        _ => None,
    }
}
