//! The one error type of the core: returned by validation, never by the
//! per-sample path (which saturates instead).

use core::fmt;

/// Why a parameter set, a load or a blob was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// A parameter is NaN or infinite; the name says which.
    NonFinite(&'static str),
    /// A parameter is outside its physical range; the name says which and the
    /// text what was expected.
    OutOfRange(&'static str, &'static str),
    /// The four critical points give a singular system (two points share a
    /// contraction, or the elimination of eqs. 8–10 divides by zero).
    Singular,
    /// The cubic has more than one real root (`b² − 4ac ≥ 0` in eq. 3), which
    /// the paper's monotone constraint model excludes. The load is given.
    NotOneRealRoot {
        /// Load at which the check failed, in newtons.
        load_n: f32,
    },
    /// The constraint model is not strictly increasing on `[R_i, Rx_i]`, so it
    /// has no inverse. The load and the contraction where the slope is lowest
    /// are given.
    NotMonotone {
        /// Load at which the check failed, in newtons.
        load_n: f32,
        /// Contraction where the slope is lowest.
        contraction: f32,
    },
    /// A load outside the calibrated range was asked for.
    LoadOutOfRange {
        /// The load asked for, in newtons.
        load_n: f32,
    },
    /// A coefficient blob is malformed: the text says how.
    Blob(&'static str),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::NonFinite(name) => write!(f, "parameter `{name}` is not finite"),
            Error::OutOfRange(name, want) => write!(f, "parameter `{name}` out of range: {want}"),
            Error::Singular => write!(
                f,
                "critical points give a singular system (repeated contraction?)"
            ),
            Error::NotOneRealRoot { load_n } => write!(
                f,
                "constraint model at {load_n} N has more than one real root (b^2 - 4ac >= 0)"
            ),
            Error::NotMonotone {
                load_n,
                contraction,
            } => write!(
                f,
                "constraint model at {load_n} N is not increasing near contraction {contraction}"
            ),
            Error::LoadOutOfRange { load_n } => {
                write!(f, "load {load_n} N is outside the calibrated range")
            }
            Error::Blob(why) => write!(f, "coefficient blob rejected: {why}"),
        }
    }
}

impl core::error::Error for Error {}
