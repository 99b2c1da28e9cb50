//! Writes the coefficient blob the image carries in flash, and for the chip
//! build puts the workspace's `memory.x` on the linker path with cortex-m-rt's
//! and defmt's linker scripts.

use std::{env, error::Error, fs, path::PathBuf};

fn main() -> Result<(), Box<dyn Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("OUT_DIR not set")?);
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").ok_or("no manifest dir")?);

    // The blob: a file from `pam-lab fit` if PAM_COEFFS_BLOB names one (checked
    // here so a bad file fails the build, not the boot), else pam-core's
    // encoding of its default parameters.
    println!("cargo:rerun-if-env-changed=PAM_COEFFS_BLOB");
    let mut blob = match env::var_os("PAM_COEFFS_BLOB") {
        Some(path) => {
            let bytes = fs::read(&path)?;
            pam_core::blob::decode(&bytes)
                .map_err(|e| format!("PAM_COEFFS_BLOB {}: {e}", path.to_string_lossy()))?;
            println!("cargo:rerun-if-changed={}", path.to_string_lossy());
            bytes
        }
        None => pam_core::blob::encode(&pam_core::Params::DEFAULT).to_vec(),
    };
    if env::var_os("CARGO_FEATURE_QEMU_BAD_BLOB").is_some() {
        // One bit of one parameter flipped: the CRC check must refuse it at boot.
        blob[20] ^= 0x01;
    }
    fs::write(out.join("coeffs.bin"), &blob)?;

    let bare_metal = env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    if bare_metal && env::var_os("CARGO_FEATURE_RT").is_some() {
        fs::copy(manifest.join("../memory.x"), out.join("memory.x"))?;
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    Ok(())
}
