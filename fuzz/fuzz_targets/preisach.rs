//! pam-core's Preisach model: a table of perturbed geometry and arbitrary
//! weights (signed, huge, tiny) at two loads, validated, then a sequence of
//! steps (arbitrary pressures and loads, load switches spread over
//! updates) and inverse calls (arbitrary contractions), each inverse
//! result applied as a feedforward applies it.
//!
//! First the same bytes as a blob (`pam_core::preisach::blob::decode`),
//! as they come and as the payload of a correct frame (magic, version,
//! length, sizes, CRC-32): no panic; a blob that decodes re-encodes to the
//! same bytes and runs.
//!
//! Asserts after every call: the relay counts stay in `0..=i + 1`; the
//! output is finite (at any pressure within 10³ MPa); the inverse's pressure is finite
//! and in `[0, max_pressure_mpa]`; a finite contraction at or above the
//! output asks for no lower pressure than the present one (clamped to the
//! range), one below for no higher.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_core::blob::crc32;
use pam_core::preisach::blob::{self, PREISACH_BLOB_MAGIC, PREISACH_BLOB_VERSION};
use pam_core::preisach::{Preisach, PreisachCoeffs, PreisachTable};
use pam_fuzz::Floats;

const N: usize = 6;

fn check_blob(data: &[u8]) {
    const LEN: usize = blob::blob_len(N, 2);
    let _ = blob::decode::<N, 2>(data);
    let mut framed = [0u8; LEN];
    framed[0..4].copy_from_slice(&PREISACH_BLOB_MAGIC);
    framed[4..6].copy_from_slice(&PREISACH_BLOB_VERSION.to_le_bytes());
    framed[6..8].copy_from_slice(&(blob::payload_len(N, 2) as u16).to_le_bytes());
    framed[8..10].copy_from_slice(&(N as u16).to_le_bytes());
    framed[10..12].copy_from_slice(&2u16.to_le_bytes());
    let n = data.len().min(LEN - 16);
    framed[12..12 + n].copy_from_slice(&data[..n]);
    let crc = crc32(&framed[..LEN - 4]);
    framed[LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    if let Ok(t) = blob::decode::<N, 2>(&framed) {
        let mut again = [0u8; LEN];
        blob::encode(&t, &mut again).expect("the blob's own length");
        assert_eq!(again, framed, "re-encoding differs");
        let mut m = Preisach::new(&t, t.min_load_n, 0.0);
        assert!(m.step(&t, t.max_pressure_mpa, t.min_load_n).is_finite());
        let p = m.inverse_pressure_mpa(0.0);
        assert!((0.0..=t.max_pressure_mpa).contains(&p));
    }
}

fuzz_target!(|data: &[u8]| {
    check_blob(data);
    let mut f = Floats::new(data);
    let mut coeffs = || {
        let w: [[f32; N]; N] =
            core::array::from_fn(|_| core::array::from_fn(|_| f.near(0.002, 40.0)));
        PreisachCoeffs::from_weights(f.near(0.01, 2.0), f.near(0.1, 4.0), &w)
    };
    let grid = [coeffs(), coeffs()];
    let table = PreisachTable::<N, 2> {
        lo_mpa: f.near(0.01, 2.0),
        step_mpa: f.near(0.07, 1.0),
        max_pressure_mpa: f.near(0.5, 0.5),
        min_load_n: f.near(100.0, 1.0),
        load_step_n: f.near(100.0, 1.0),
        grid,
    };
    if table.validate().is_err() {
        return;
    }
    let mut m = Preisach::new(&table, f.around(50.0, 250.0), f.around(0.0, 0.5));
    while !f.is_empty() {
        if f.byte() % 3 == 0 {
            let x_now = m.output();
            let x = f.around(x_now - 0.05, x_now + 0.05);
            let p0 = m.last_mpa().clamp(0.0, table.max_pressure_mpa);
            let p = m.inverse_pressure_mpa(x);
            assert!(
                p.is_finite() && (0.0..=table.max_pressure_mpa).contains(&p),
                "inverse gave {p}"
            );
            if x.is_finite() && x_now.is_finite() {
                if x >= x_now {
                    assert!(p >= p0, "rising to {x} from {x_now}: {p} < {p0}");
                } else {
                    assert!(p <= p0, "falling to {x} from {x_now}: {p} > {p0}");
                }
            }
            m.update_state(p);
        } else {
            let x = m.step(&table, f.around(0.0, 0.5), f.around(50.0, 250.0));
            // Validated magnitudes: finite at any pressure within 10³ MPa.
            if m.last_mpa().abs() < 1e3 {
                assert!(x.is_finite(), "output {x}");
            }
        }
        for (i, &c) in m.rows_on().iter().enumerate() {
            assert!(usize::from(c) <= i + 1, "row {i}: {c} relays on");
        }
    }
});
