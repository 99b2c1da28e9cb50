//! Reports drawn as pictures: [`plot`] for `fit` and `simulate`,
//! [`diagnose_plot`] for `diagnose`.

pub mod diagnose_plot;
pub mod plot;
