//! The firmware's coefficient-blob decoder, `pam_core::blob::decode`, on
//! arbitrary bytes, and on arbitrary payloads inside a correct frame (magic,
//! version, length, CRC-32), which random bytes would almost never pass.
//!
//! Asserts: no panic; a blob that decodes re-encodes to the same bytes and is
//! a model that runs (finite, non-empty stroke at both ends of the load
//! range); `decode` accepts exactly when `decode_params` and `Coeffs::new` do.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_core::blob::{self, BLOB_LEN, BLOB_MAGIC, BLOB_VERSION, PAYLOAD_LEN};
use pam_core::Coeffs;
use pam_fuzz::check_coeffs;

fn check(bytes: &[u8]) {
    let decoded = blob::decode(bytes);
    let params = blob::decode_params(bytes);
    match &decoded {
        Ok(c) => {
            assert_eq!(params.as_ref().ok(), Some(c.params()));
            assert_eq!(&blob::encode(c.params())[..], bytes, "re-encoding differs");
            check_coeffs(c);
        }
        Err(_) => {
            if let Ok(p) = params {
                assert!(Coeffs::new(p).is_err());
            }
        }
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    // A correct frame around the first PAYLOAD_LEN bytes (zero-padded).
    let mut framed = [0u8; BLOB_LEN];
    framed[0..4].copy_from_slice(&BLOB_MAGIC);
    framed[4..6].copy_from_slice(&BLOB_VERSION.to_le_bytes());
    framed[6..8].copy_from_slice(&(PAYLOAD_LEN as u16).to_le_bytes());
    let n = data.len().min(PAYLOAD_LEN);
    framed[8..8 + n].copy_from_slice(&data[..n]);
    let crc = blob::crc32(&framed[..8 + PAYLOAD_LEN]);
    framed[8 + PAYLOAD_LEN..].copy_from_slice(&crc.to_le_bytes());
    check(&framed);
});
