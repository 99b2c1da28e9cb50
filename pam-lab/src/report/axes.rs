//! The axis labels of every plot the tools draw (pam-lab's and host-sim's):
//! one name and one unit per quantity, the unit in parentheses, an error
//! always model − measured.

/// Time since the record's first sample.
pub const TIME_S: &str = "time (s)";
/// Pressure.
pub const PRESSURE_MPA: &str = "pressure (MPa)";
/// Contraction, `(rest length − length) / rest length`.
pub const CONTRACTION: &str = "contraction (fraction of rest length)";
/// The force on the muscle: the hung load of an isotonic test, the
/// measured force of an isometric one.
pub const FORCE_N: &str = "force on the muscle, the load (N)";
/// A contraction error.
pub const CONTRACTION_ERROR: &str = "model − measured contraction (fraction of rest length)";
/// A pressure error.
pub const PRESSURE_ERROR_MPA: &str = "model − measured pressure (MPa)";

/// Every label above.
pub const ALL: [&str; 6] = [
    TIME_S,
    PRESSURE_MPA,
    CONTRACTION,
    FORCE_N,
    CONTRACTION_ERROR,
    PRESSURE_ERROR_MPA,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_label_ends_with_its_unit_in_parentheses_and_errors_are_model_minus_measured() {
        for l in ALL {
            let open = l.rfind(" (").unwrap_or_else(|| panic!("{l}: no unit"));
            assert!(l.ends_with(')') && open + 3 < l.len(), "{l}");
            let after_comma = l.rsplit(", ").next().unwrap_or(l);
            assert!(
                after_comma.contains(" ("),
                "{l}: the unit is not after a comma"
            );
            if l.contains("error") || l.contains('−') {
                assert!(l.starts_with("model − measured "), "{l}");
            }
        }
    }
}
