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
            pam_core::blob::decode_model(&bytes)
                .map_err(|e| format!("PAM_COEFFS_BLOB {}: {e}", path.to_string_lossy()))?;
            println!("cargo:rerun-if-changed={}", path.to_string_lossy());
            bytes
        }
        None if env::var_os("CARGO_FEATURE_QEMU_MEMORY_BLOB").is_some() => {
            // A version-2 blob with non-local memory, as `pam-lab diagnose`
            // writes for a record with memory (shape and merge span of the
            // self-test: see firmware::scenario::MEMORY_BLOB_EFFECTS).
            let effects = pam_core::Effects {
                memory: Some(pam_core::effects::NonLocalMemory {
                    shape: 1.0,
                    merge_span: 0.02,
                }),
                ..pam_core::Effects::NONE
            };
            pam_core::blob::encode_v2(&pam_core::Params::DEFAULT, &effects).to_vec()
        }
        None if env::var_os("CARGO_FEATURE_QEMU_EFFECTS_BLOB").is_some() => {
            // A version-2 blob with every effect that version carries (the
            // self-test's: see firmware::scenario::EFFECTS_BLOB_EFFECTS).
            use pam_core::effects::*;
            let effects = pam_core::Effects {
                memory: Some(NonLocalMemory {
                    shape: 1.0,
                    merge_span: 0.02,
                }),
                rate: Some(RateDependence::linear(1.0, 0.5)),
                creep: Some(Creep {
                    gain: 0.05,
                    time_constant_s: 0.5,
                }),
                width: Some(LoadDependentWidth {
                    scale_at_min_load: 1.0,
                    scale_per_step: 0.05,
                }),
                shape: Some(ConstraintShape {
                    bulge: 0.05,
                    tilt: 0.0,
                    bulge_per_step: 0.0,
                    tilt_per_step: 0.0,
                    ..ConstraintShape::NEUTRAL
                }),
                // Version 4's effect: not in this version-2 blob.
                pressure_lag: None,
            };
            pam_core::blob::encode_v2(&pam_core::Params::DEFAULT, &effects).to_vec()
        }
        None => pam_core::blob::encode(&pam_core::Params::DEFAULT).to_vec(),
    };
    println!("cargo:rerun-if-env-changed=CARGO_FEATURE_QEMU_MEMORY_BLOB");
    println!("cargo:rerun-if-env-changed=CARGO_FEATURE_QEMU_EFFECTS_BLOB");
    if env::var_os("CARGO_FEATURE_QEMU_BAD_BLOB").is_some() {
        // One bit of one parameter flipped: the CRC check must refuse it at boot.
        blob[20] ^= 0x01;
    }
    if blob.len() > pam_core::blob::MAX_BLOB_LEN {
        return Err(format!(
            "coefficient blob of {} bytes is longer than any version",
            blob.len()
        )
        .into());
    }
    // The flash region holds the longest blob of any version; a shorter one
    // is followed by erased flash (0xFF), its header giving its length.
    blob.resize(pam_core::blob::MAX_BLOB_LEN, 0xFF);
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
