//! Identification: a model from a record. [`fit`] finds the paper's model
//! (one load family), [`diagnose`] adds the effects the residual shows,
//! [`reference`](mod@reference) is the generic static surface both are measured against;
//! [`lsq`] is the least-squares plumbing they share.

pub mod diagnose;
pub mod fit;
pub mod lsq;
pub mod reference;
