//! The main job's command line: a bad option is one located `error:` line
//! and exit code 1, not a debug dump.

use std::process::Command;

#[test]
fn bad_options_are_named_with_what_is_expected() {
    for (args, want) in [
        (
            &["--seed", "abc"][..],
            "error: --seed `abc`: expected a whole number >= 0",
        ),
        (&["--kp"][..], "error: --kp needs a gain in MPa"),
        (
            &["--ki", "fast"][..],
            "error: --ki `fast`: expected a gain in MPa/s",
        ),
        (&["--bogus"][..], "error: unknown argument \"--bogus\""),
        (
            &["--ki", "-1"][..],
            "error: controller settings refused (FF+PI): ",
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.starts_with(want), "{args:?}: {stderr}");
        assert!(!stderr.contains("ParseIntError"), "{stderr}");
        assert!(
            !stderr.contains("{ ") && !stderr.contains("Error"),
            "a debug dump: {stderr}"
        );
    }
}
