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

mod checks;
mod error;
pub mod import;
mod reader;
pub mod split;
mod statistics;
#[cfg(test)]
mod tests;

pub use checks::*;
pub use error::*;
pub use reader::*;
pub use statistics::*;

/// The columns the tools need, in the order of [`Sample`]'s fields.
pub const COLUMNS: [&str; 4] = ["t_s", "load_n", "pressure_mpa", "contraction"];

/// Lowest physically possible gauge pressure, MPa: absolute vacuum.
pub const MIN_PRESSURE_MPA: f64 = -0.101_325;
/// Highest pressure accepted, MPa (the model's own limit on `Pmax`).
pub const MAX_PRESSURE_MPA: f64 = 10.0;
/// Highest load accepted, N. A muscle only pulls, so loads are `>= 0`.
pub const MAX_LOAD_N: f64 = 100_000.0;

/// Most samples a record may have (a 2-hour test at 100 Hz is 720 000).
/// Longer records are refused, not read into memory without bound:
/// decimate them first.
pub const MAX_ROWS: usize = 1_000_000;
/// Most bytes a record file may have, 64 MiB.
pub const MAX_BYTES: u64 = 64 << 20;

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
    /// Where the record's parts begin, in sample order: a `# segment:
    /// LABEL` comment line, as `pam-lab import` writes one at each file it
    /// joins and each clock reset. Empty for a record of one run.
    pub segments: Vec<Segment>,
}

/// The comment that marks where a record's next part begins: `# segment:
/// LABEL` on a line of its own, before the part's first sample.
pub const SEGMENT_COMMENT: &str = "segment:";

/// Where one part of a record begins (a test, a file, a run after a clock
/// reset).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Segment {
    /// Index of the part's first sample.
    pub start: usize,
    /// What the comment says about it (`10mm_15cm_Unkink_Test8.csv (new file)`).
    pub label: String,
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
            segments: Vec::new(),
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

    /// The samples `i` with `keep(i)`, as a record named `source`: each
    /// sample keeps its line, each segment starts at its first kept sample
    /// (a segment with none is dropped).
    pub fn subset(&self, source: String, keep: impl Fn(usize) -> bool) -> Record {
        let mut out = Record {
            source,
            ..Record::default()
        };
        let mut seams = self.segments.iter().peekable();
        let mut pending = None;
        for (i, s) in self.samples.iter().enumerate() {
            while let Some(seam) = seams.next_if(|seam| seam.start <= i) {
                pending = Some(seam);
            }
            if keep(i) {
                if let Some(seam) = pending.take() {
                    out.segments.push(Segment {
                        start: out.samples.len(),
                        label: seam.label.clone(),
                    });
                }
                out.samples.push(*s);
                out.lines.push(self.line(i));
            }
        }
        out
    }

    /// The record's parts as sample ranges with their labels: samples
    /// before the first seam form a part labelled `(start)`. Empty for a
    /// record without seams.
    pub fn segment_ranges(&self) -> Vec<(&str, std::ops::Range<usize>)> {
        let n = self.samples.len();
        let mut out = Vec::with_capacity(self.segments.len() + 1);
        if let Some(first) = self.segments.first() {
            if first.start > 0 {
                out.push(("(start)", 0..first.start.min(n)));
            }
        }
        for (k, seam) in self.segments.iter().enumerate() {
            let end = self.segments.get(k + 1).map_or(n, |next| next.start).min(n);
            out.push((seam.label.as_str(), seam.start.min(end)..end));
        }
        out
    }
}
