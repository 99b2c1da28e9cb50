//! Reproducers of the crashes the fuzz targets (`fuzz/`, run with nightly
//! `cargo fuzz`) found, kept as stable tests. Each names its target and the
//! defect; `fuzz/README.md` has the table of runs.

use pam_core::{blob, Coeffs, Error, Params};

/// The 14 `Params` fields from raw `f32` bits, in blob order.
fn params_from_bits(bits: [u32; 14]) -> Params {
    let mut payload = [0u8; blob::PAYLOAD_LEN];
    for (chunk, b) in payload.chunks_exact_mut(4).zip(bits) {
        chunk.copy_from_slice(&b.to_le_bytes());
    }
    let mut framed = [0u8; blob::BLOB_LEN];
    framed[0..4].copy_from_slice(&blob::BLOB_MAGIC);
    framed[4..6].copy_from_slice(&blob::BLOB_VERSION.to_le_bytes());
    framed[6..8].copy_from_slice(&(blob::PAYLOAD_LEN as u16).to_le_bytes());
    framed[8..8 + blob::PAYLOAD_LEN].copy_from_slice(&payload);
    let crc = blob::crc32(&framed[..8 + blob::PAYLOAD_LEN]);
    framed[8 + blob::PAYLOAD_LEN..].copy_from_slice(&crc.to_le_bytes());
    blob::decode_params(&framed).expect("framing is correct")
}

/// blob_decode, 2026-11-21: a framed blob whose regressions per step are
/// 1.47e13 was accepted (the `(-1, 1)` bounds on `R1`, `Rx1` were checked at
/// the minimum load only), and the model at 600 N had the empty f32 stroke
/// `[-2.93e13, -2.93e13]`.
/// Fixed in `Coeffs::new`: `-1 < R_i < Rx_i < 1` at every checked load, the
/// last comparison in f32.
#[test]
fn regressions_that_push_the_stroke_out_of_range_are_refused() {
    // crash-994558f7c9a9de0fbfc5afc787db72951935a61b: 400–600 N, step 100 N,
    // R1 a subnormal, Rx1 0.25, RG_L = RG_U = 1.466e13 per step.
    let p = params_from_bits([
        0x43c8_0000,
        0x4416_0000,
        0x42c8_0000,
        0x0000_4fbc,
        0x3e80_0060,
        0x3f00_2c00,
        0x3d8f_5c29,
        0x2b2b_0b2b,
        0x2b2b_2b2b,
        0x2b2b_2b2b,
        0x5555_5555,
        0x5555_5555,
        0x2b2b_5555,
        0x0000_0000,
    ]);
    assert_eq!(p.root_regression_per_step, 14_660_154_687_488.0);
    assert!(matches!(
        Coeffs::new(p),
        Err(Error::OutOfRange("root_regression_per_step", _))
    ));
    assert!(blob::decode(&blob::encode(&p)).is_err());
}

/// Whatever `Coeffs::new` accepts has a non-empty f32 stroke inside `(-1, 1)`
/// at both ends of the load range (the invariant the fuzz targets assert).
#[test]
fn default_stroke_is_non_empty_at_both_ends() {
    let c = Coeffs::new(Params::DEFAULT).unwrap();
    for load_n in [100.0, 600.0] {
        let m = c.load_model(load_n).unwrap();
        assert!(-1.0 < m.root_contraction() && m.root_contraction() < m.max_contraction());
        assert!(m.max_contraction() < 1.0);
    }
}

/// core_eval, 2026-11-21: with `be` = 1.28e-22 MPa the stored `(be/ae)²` was
/// an f32 subnormal and `offset_mpa` came out 1 % above `be` (an absolute
/// error of 1e-24 MPa, but outside the documented range). Fixed in
/// `Coeffs::new`: a non-zero `be` below 1e-6 MPa (1 Pa) is refused.
#[test]
fn a_subnormal_squared_ellipse_height_is_refused() {
    let mut p = Params::DEFAULT;
    p.ellipse_height_mpa = 1.28e-22;
    assert!(matches!(
        Coeffs::new(p),
        Err(Error::OutOfRange("ellipse_height_mpa", _))
    ));
    p.ellipse_height_mpa = 0.0;
    let c = Coeffs::new(p).unwrap();
    let m = c.load_model_clamped(200.0);
    assert_eq!(
        m.offset_mpa(0.5 * (m.root_contraction() + m.max_contraction())),
        0.0
    );
    p.ellipse_height_mpa = pam_core::coeffs::MIN_ELLIPSE_HEIGHT_MPA;
    let m = Coeffs::new(p).unwrap().load_model_clamped(200.0);
    let peak = m.offset_mpa(0.5 * (m.root_contraction() + m.max_contraction()));
    assert!(
        peak <= p.ellipse_height_mpa * (1.0 + 4.0 * f32::EPSILON),
        "{peak}"
    );
}
