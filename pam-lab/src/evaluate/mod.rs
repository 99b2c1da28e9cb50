//! Evaluation: a model driven over a record ([`simulate`], pam-core's
//! simulator, the one record simulator) and its errors against the
//! measurement ([`errors`]: per load and branch, noise floor, correlation);
//! [`families`]: a record on the accuracy × instructions plane, fit's model
//! beside the Preisach model; [`retime`]: a record's pressure moved in time
//! against its other channels (a pressure delay); [`segments`]: the errors
//! per part (test) of a joined record.

pub mod crossing;
pub mod errors;
pub mod families;
pub mod retime;
pub mod segments;
pub mod simulate;
