//! Running the `pam-lab` binary from a test.

use std::process::Command;

/// Run `pam-lab args`: whether it succeeded, its stdout and its stderr.
pub fn pam_lab(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_pam-lab"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}
