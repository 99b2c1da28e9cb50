//! Reports drawn as pictures: [`plot`] for `fit` and `simulate`,
//! [`diagnose_plot`] for `diagnose`, [`compare_plot`] for `compare`, their
//! axis labels in [`axes`].

pub mod axes;
pub mod compare_plot;
pub mod diagnose_plot;
pub mod plot;
