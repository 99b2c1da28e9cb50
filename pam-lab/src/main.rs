//! `pam-lab`: see the crate docs.
fn main() {}
