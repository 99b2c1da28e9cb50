//! Reports drawn as pictures: [`plot`] for `fit` and `simulate`,
//! [`diagnose_plot`] for `diagnose`, their axis labels in [`axes`].

pub mod axes;
pub mod diagnose_plot;
pub mod plot;
