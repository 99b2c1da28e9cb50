//! The coefficient blob the firmware keeps in flash and `pam-lab fit` writes.
//!
//! Layout, little-endian, [`BLOB_LEN`] bytes:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"PAMC"` |
//! | 4 | 2 | format version ([`BLOB_VERSION`]) |
//! | 6 | 2 | payload length in bytes ([`PAYLOAD_LEN`]) |
//! | 8 | 56 | the 14 `f32` fields of [`Params`], in declaration order |
//! | 64 | 4 | CRC-32 (IEEE 802.3, as zlib's `crc32`) of bytes 0..64 |
//!
//! [`decode`] checks magic, version, length and CRC, then validates the
//! parameters with [`Coeffs::new`]: a blob that decodes is a model that runs.

use crate::coeffs::Coeffs;
use crate::error::Error;
use crate::params::{CriticalPoints, Params, Point};

/// Magic bytes at the start of a blob.
pub const BLOB_MAGIC: [u8; 4] = *b"PAMC";
/// Format version this crate writes and reads.
pub const BLOB_VERSION: u16 = 1;
/// Number of `f32` fields in the payload.
pub const PAYLOAD_FIELDS: usize = Params::FIELD_COUNT;
/// Payload length, bytes.
pub const PAYLOAD_LEN: usize = 4 * PAYLOAD_FIELDS;
/// Total blob length, bytes.
pub const BLOB_LEN: usize = 8 + PAYLOAD_LEN + 4;

fn fields(p: &Params) -> [f32; PAYLOAD_FIELDS] {
    p.named_fields().map(|(_, v)| v)
}

fn from_fields(f: &[f32; PAYLOAD_FIELDS]) -> Params {
    Params {
        min_load_n: f[0],
        max_load_n: f[1],
        load_step_n: f[2],
        points: CriticalPoints {
            root_contraction: f[3],
            max_contraction: f[4],
            max_pressure_mpa: f[5],
            tangency: Point {
                contraction: f[6],
                pressure_mpa: f[7],
            },
            inflection: Point {
                contraction: f[8],
                pressure_mpa: f[9],
            },
        },
        root_regression_per_step: f[10],
        max_regression_per_step: f[11],
        c_growth_per_step: f[12],
        ellipse_height_mpa: f[13],
    }
}

/// CRC-32/IEEE (reflected, polynomial 0xEDB88320), bitwise: small code, and
/// it runs once at boot.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !crc
}

/// Encode `params` (not validated here: validate with [`Coeffs::new`] first).
pub fn encode(params: &Params) -> [u8; BLOB_LEN] {
    let mut out = [0u8; BLOB_LEN];
    out[0..4].copy_from_slice(&BLOB_MAGIC);
    out[4..6].copy_from_slice(&BLOB_VERSION.to_le_bytes());
    out[6..8].copy_from_slice(&(PAYLOAD_LEN as u16).to_le_bytes());
    for (chunk, v) in out[8..8 + PAYLOAD_LEN]
        .chunks_exact_mut(4)
        .zip(fields(params))
    {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    let crc = crc32(&out[..8 + PAYLOAD_LEN]);
    out[8 + PAYLOAD_LEN..].copy_from_slice(&crc.to_le_bytes());
    out
}

/// Decode and validate a blob; any defect is an [`Error::Blob`] or the
/// validation error of [`Coeffs::new`].
pub fn decode(bytes: &[u8]) -> Result<Coeffs, Error> {
    decode_params(bytes).and_then(Coeffs::new)
}

/// Decode a blob to its parameters, checking framing and CRC only.
pub fn decode_params(bytes: &[u8]) -> Result<Params, Error> {
    if bytes.len() != BLOB_LEN {
        return Err(Error::Blob("wrong length"));
    }
    if bytes[0..4] != BLOB_MAGIC {
        return Err(Error::Blob("bad magic"));
    }
    if u16::from_le_bytes([bytes[4], bytes[5]]) != BLOB_VERSION {
        return Err(Error::Blob("unsupported version"));
    }
    if usize::from(u16::from_le_bytes([bytes[6], bytes[7]])) != PAYLOAD_LEN {
        return Err(Error::Blob("wrong payload length"));
    }
    let body = 8 + PAYLOAD_LEN;
    let stored = u32::from_le_bytes([
        bytes[body],
        bytes[body + 1],
        bytes[body + 2],
        bytes[body + 3],
    ]);
    if crc32(&bytes[..body]) != stored {
        return Err(Error::Blob("CRC mismatch"));
    }
    let mut f = [0f32; PAYLOAD_FIELDS];
    for (v, chunk) in f.iter_mut().zip(bytes[8..body].chunks_exact(4)) {
        *v = f32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
    }
    Ok(from_fields(&f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_matches_the_standard_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn round_trip() {
        let blob = encode(&Params::DEFAULT);
        assert_eq!(decode(&blob).unwrap().params(), &Params::DEFAULT);
    }

    #[test]
    fn every_single_bit_flip_is_refused() {
        let blob = encode(&Params::DEFAULT);
        for i in 0..BLOB_LEN * 8 {
            let mut b = blob;
            b[i / 8] ^= 1 << (i % 8);
            assert!(decode(&b).is_err(), "bit {i}");
        }
    }

    #[test]
    fn framing_errors_are_named() {
        let blob = encode(&Params::DEFAULT);
        assert_eq!(decode(&blob[..10]), Err(Error::Blob("wrong length")));
        let mut b = blob;
        b[0] = b'X';
        assert_eq!(decode(&b), Err(Error::Blob("bad magic")));
        let mut b = blob;
        b[4] = 9;
        assert_eq!(decode(&b), Err(Error::Blob("unsupported version")));
    }

    #[test]
    fn a_valid_frame_around_invalid_params_is_refused() {
        let mut p = Params::DEFAULT;
        p.ellipse_height_mpa = f32::NAN;
        assert_eq!(
            decode(&encode(&p)),
            Err(Error::NonFinite("ellipse_height_mpa"))
        );
    }
}
