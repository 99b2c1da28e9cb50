//! pam-lab's model file reader, `model_file::load` (a JSON model file or a
//! coefficient blob, told apart by the blob's magic), on arbitrary bytes.
//!
//! `load` takes a path, so each input is written to one scratch file per
//! fuzzing process (in `/dev/shm` when there is one, else the temp
//! directory) and read back through it.
//!
//! Asserts: no panic; an accepted model re-validates with `Coeffs::new` and
//! runs (finite, non-empty stroke at both ends of the load range); the error
//! text names the file.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use pam_core::Coeffs;
use pam_fuzz::check_coeffs;
use pam_lab::export::model_file;

fn scratch() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        // cargo-fuzz sets RUST_BACKTRACE=1, which makes every `anyhow` error
        // capture a backtrace (measured: 296 -> 477 exec/s). Panics keep
        // theirs; this only turns off error-value backtraces, and is set
        // before the first error is made.
        std::env::set_var("RUST_LIB_BACKTRACE", "0");
        // A file on disk costs milliseconds per write (477 exec/s); on tmpfs
        // the target runs at about 17 000 exec/s.
        let shm = std::path::Path::new("/dev/shm");
        let dir = if shm.is_dir() {
            shm.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        dir.join(format!("pam-fuzz-model-{}.bin", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    std::fs::write(path, data).expect("scratch file writable");
    match model_file::load(path) {
        Ok(m) => {
            let c = m.coeffs;
            assert_eq!(Coeffs::new(*c.params()).as_ref(), Ok(&c));
            assert_eq!(m.effects.validate(), Ok(()));
            check_coeffs(&c);
        }
        Err(e) => {
            let text = format!("{e:#}");
            assert!(
                text.contains(&*path.to_string_lossy()),
                "error without the file: {text}"
            );
        }
    }
});
