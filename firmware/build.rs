//! Writes the coefficient blob the image carries in flash, and for the chip
//! build puts the workspace's `memory.x` on the linker path with cortex-m-rt's
//! and defmt's linker scripts.

use std::{env, error::Error, fs, path::PathBuf};

/// The Preisach blob's size the images boot: `firmware::controller::preisach`'s
/// `PREISACH_ROWS` and `PREISACH_LOADS` (a build script cannot use its own
/// crate; the region's length ties them: see `firmware::BLOB_REGION_LEN`).
const PREISACH_ROWS: usize = 16;
const PREISACH_LOADS: usize = 6;

fn main() -> Result<(), Box<dyn Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("OUT_DIR not set")?);
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").ok_or("no manifest dir")?);

    // The blob: a file from `pam-lab fit`, `diagnose` or `compare` (its
    // `preisach.blob`) if PAM_COEFFS_BLOB names one (checked here so a bad
    // file fails the build, not the boot), else pam-core's encoding of its
    // default parameters.
    println!("cargo:rerun-if-env-changed=PAM_COEFFS_BLOB");
    let mut blob = match env::var_os("PAM_COEFFS_BLOB") {
        Some(path) => {
            let bytes = fs::read(&path)?;
            let checked =
                if bytes.get(..4) == Some(&pam_core::preisach::blob::PREISACH_BLOB_MAGIC[..]) {
                    pam_core::preisach::blob::decode::<PREISACH_ROWS, PREISACH_LOADS>(&bytes)
                        .map(|_| ())
                } else {
                    pam_core::blob::decode_model(&bytes).map(|_| ())
                };
            checked.map_err(|e| format!("PAM_COEFFS_BLOB {}: {e}", path.to_string_lossy()))?;
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
                pressure_delay: None,
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
    // The flash region holds the longest blob the images boot
    // (`firmware::BLOB_REGION_LEN`, which must be this length: the image's
    // array has no other size); a shorter one is followed by erased flash
    // (0xFF), its header giving its length.
    let region_len = pam_core::blob::MAX_BLOB_LEN.max(pam_core::preisach::blob::blob_len(
        PREISACH_ROWS,
        PREISACH_LOADS,
    ));
    if blob.len() > region_len {
        return Err(format!(
            "blob of {} bytes is longer than the flash region ({region_len} bytes)",
            blob.len()
        )
        .into());
    }
    blob.resize(region_len, 0xFF);
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
