//! Identification: a model from a record. [`fit`] finds the paper's model
//! (one load family), [`diagnose`] adds the effects the residual shows,
//! [`reference`](mod@reference) is the generic static surface both are measured against;
//! [`lsq`] is the least-squares plumbing they share; [`adapted`] turns the
//! stroke scale the firmware adapted online into a paper model of its own;
//! [`preisach`] identifies the second model family pam-core carries.

pub mod adapted;
pub mod diagnose;
pub mod fit;
pub mod lsq;
pub mod preisach;
pub mod reference;
