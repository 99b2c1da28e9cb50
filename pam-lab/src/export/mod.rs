//! Export: what leaves pam-lab for the firmware and the user ([`model_file`]:
//! the JSON model, the coefficient blob, the Rust constants).

pub mod model_file;
