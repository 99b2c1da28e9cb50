//! The Preisach model's blob: its table as `pam-lab compare` writes it and
//! a controller would keep it in flash, framed and checked as the paper
//! model's blob is ([`crate::blob`]: magic, version, payload length,
//! CRC-32), with a magic of its own so that neither reader mistakes the
//! other's blob.
//!
//! Layout, little-endian, [`blob_len`]`(N, L)` bytes:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"PAMP"` |
//! | 4 | 2 | format version ([`PREISACH_BLOB_VERSION`]) |
//! | 6 | 2 | payload length in bytes |
//! | 8 | 2 | `N`, relay rows |
//! | 10 | 2 | `L`, grid loads |
//! | 12 | 20 | `lo_mpa`, `step_mpa`, `max_pressure_mpa`, `min_load_n`, `load_step_n` (`f32`) |
//! | 32 | `L·(2 + N²)·4` | per grid load: `bias`, `linear`, the Everett function row by row (`f32`) |
//! | end − 4 | 4 | CRC-32 of everything before it |
//!
//! [`decode`] checks the framing, that `N` and `L` are the reader's, the
//! CRC, and validates the table ([`PreisachTable::validate`]): a blob that
//! decodes is a model that runs.

use super::table::{PreisachCoeffs, PreisachTable};
use crate::blob::crc32;
use crate::error::Error;

/// Magic bytes at the start of a Preisach blob.
pub const PREISACH_BLOB_MAGIC: [u8; 4] = *b"PAMP";
/// Format version.
pub const PREISACH_BLOB_VERSION: u16 = 1;

/// Payload length of a table of `n` rows at `l` loads, bytes.
pub const fn payload_len(n: usize, l: usize) -> usize {
    4 + 5 * 4 + l * (2 + n * n) * 4
}

/// Blob length of a table of `n` rows at `l` loads, bytes.
pub const fn blob_len(n: usize, l: usize) -> usize {
    8 + payload_len(n, l) + 4
}

/// Write `table` into `out`, which must be exactly [`blob_len`]`(N, L)`
/// bytes (and the payload under 64 KiB); the table is not validated here
/// (validate it first).
pub fn encode<const N: usize, const L: usize>(
    table: &PreisachTable<N, L>,
    out: &mut [u8],
) -> Result<(), Error> {
    let payload = payload_len(N, L);
    if out.len() != blob_len(N, L) {
        return Err(Error::Blob("output buffer is not the blob's length"));
    }
    let (Ok(payload_u16), Ok(n), Ok(l)) =
        (u16::try_from(payload), u16::try_from(N), u16::try_from(L))
    else {
        return Err(Error::Blob("table too large for the format"));
    };
    let mut w = Writer { out, at: 0 };
    w.bytes(&PREISACH_BLOB_MAGIC);
    w.bytes(&PREISACH_BLOB_VERSION.to_le_bytes());
    w.bytes(&payload_u16.to_le_bytes());
    w.bytes(&n.to_le_bytes());
    w.bytes(&l.to_le_bytes());
    for v in [
        table.lo_mpa,
        table.step_mpa,
        table.max_pressure_mpa,
        table.min_load_n,
        table.load_step_n,
    ] {
        w.bytes(&v.to_le_bytes());
    }
    for c in &table.grid {
        w.bytes(&c.bias.to_le_bytes());
        w.bytes(&c.linear.to_le_bytes());
        for v in c.everett.iter().flatten() {
            w.bytes(&v.to_le_bytes());
        }
    }
    let body = w.at;
    let crc = crc32(w.out.get(..body).unwrap_or(&[]));
    w.bytes(&crc.to_le_bytes());
    Ok(())
}

/// Length of the Preisach blob framed at the start of `bytes` (its
/// header's payload length plus header and CRC), for a blob stored in a
/// larger flash region; `None` without this format's magic and version
/// there or when the region is shorter. Nothing is checked beyond the
/// header: [`decode`] checks the rest.
pub fn framed_len(bytes: &[u8]) -> Option<usize> {
    let head = bytes.get(0..8)?;
    if head.get(0..4)? != PREISACH_BLOB_MAGIC {
        return None;
    }
    let version = u16::from_le_bytes([*head.get(4)?, *head.get(5)?]);
    if version != PREISACH_BLOB_VERSION {
        return None;
    }
    let len = 8 + usize::from(u16::from_le_bytes([*head.get(6)?, *head.get(7)?])) + 4;
    (len <= bytes.len()).then_some(len)
}

/// Read and validate a blob of a table of `N` rows at `L` loads; any
/// defect is an [`Error::Blob`] or the table's validation error.
pub fn decode<const N: usize, const L: usize>(bytes: &[u8]) -> Result<PreisachTable<N, L>, Error> {
    if bytes.len() != blob_len(N, L) {
        return Err(Error::Blob("wrong length"));
    }
    let mut r = Reader { bytes, at: 0 };
    if r.take::<4>() != PREISACH_BLOB_MAGIC {
        return Err(Error::Blob("bad magic"));
    }
    if u16::from_le_bytes(r.take()) != PREISACH_BLOB_VERSION {
        return Err(Error::Blob("unsupported version"));
    }
    if usize::from(u16::from_le_bytes(r.take())) != payload_len(N, L) {
        return Err(Error::Blob("wrong payload length"));
    }
    let body = bytes.len() - 4;
    let stored = bytes
        .get(body..)
        .and_then(|c| <[u8; 4]>::try_from(c).ok())
        .map_or(0, u32::from_le_bytes);
    if crc32(bytes.get(..body).unwrap_or(&[])) != stored {
        return Err(Error::Blob("CRC mismatch"));
    }
    if usize::from(u16::from_le_bytes(r.take())) != N
        || usize::from(u16::from_le_bytes(r.take())) != L
    {
        return Err(Error::Blob("relay rows or grid loads not this reader's"));
    }
    let mut f = || f32::from_le_bytes(r.take());
    let (lo_mpa, step_mpa, max_pressure_mpa, min_load_n, load_step_n) = (f(), f(), f(), f(), f());
    let mut grid = [PreisachCoeffs::ZERO; L];
    for c in &mut grid {
        c.bias = f();
        c.linear = f();
        for v in c.everett.iter_mut().flatten() {
            *v = f();
        }
    }
    let table = PreisachTable {
        lo_mpa,
        step_mpa,
        max_pressure_mpa,
        min_load_n,
        load_step_n,
        grid,
    };
    table.validate()?;
    Ok(table)
}

/// Sequential writes into a buffer of the right length (checked by the
/// caller; a write past the end is dropped, never a panic).
struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) {
        if let Some(slot) = self.out.get_mut(self.at..self.at + b.len()) {
            slot.copy_from_slice(b);
        }
        self.at += b.len();
    }
}

/// Sequential reads (zeros past the end, never a panic; the caller checks
/// the length first).
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const K: usize>(&mut self) -> [u8; K] {
        let out = self
            .bytes
            .get(self.at..self.at + K)
            .and_then(|c| <[u8; K]>::try_from(c).ok())
            .unwrap_or([0; K]);
        self.at += K;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> PreisachTable<4, 2> {
        let c = |s: f32| {
            let w: [[f32; 4]; 4] =
                core::array::from_fn(|i| core::array::from_fn(|j| s * (1 + i + 2 * j) as f32));
            PreisachCoeffs::from_weights(0.01 * s, 0.1 * s, &w)
        };
        PreisachTable {
            lo_mpa: 0.02,
            step_mpa: 0.1,
            max_pressure_mpa: 0.45,
            min_load_n: 100.0,
            load_step_n: 250.0,
            grid: [c(0.001), c(0.003)],
        }
    }

    #[test]
    fn a_table_round_trips_bit_for_bit() {
        let t = table();
        let mut blob = [0u8; blob_len(4, 2)];
        encode(&t, &mut blob).unwrap();
        assert_eq!(&blob[..4], b"PAMP");
        assert_eq!(decode::<4, 2>(&blob).unwrap(), t);
        assert!(encode(&t, &mut [0u8; 10]).is_err());
        // In a larger, erased region the header says where it ends.
        let mut region = [0xFFu8; blob_len(4, 2) + 40];
        region[..blob.len()].copy_from_slice(&blob);
        assert_eq!(framed_len(&region), Some(blob.len()));
        assert_eq!(framed_len(&region[..blob.len() - 1]), None);
        assert_eq!(framed_len(&[0xFF; 64]), None);
    }

    #[test]
    fn every_single_bit_flip_and_every_truncation_is_refused() {
        let mut blob = [0u8; blob_len(4, 2)];
        encode(&table(), &mut blob).unwrap();
        for byte in 0..blob.len() {
            for bit in 0..8 {
                let mut b = blob;
                b[byte] ^= 1 << bit;
                assert!(decode::<4, 2>(&b).is_err(), "byte {byte} bit {bit}");
            }
        }
        for len in 0..blob.len() {
            assert!(decode::<4, 2>(&blob[..len]).is_err(), "{len}");
        }
    }

    #[test]
    fn another_readers_size_and_an_invalid_table_are_refused() {
        let mut blob = [0u8; blob_len(4, 2)];
        encode(&table(), &mut blob).unwrap();
        assert_eq!(decode::<4, 3>(&blob), Err(Error::Blob("wrong length")),);
        let mut bad = table();
        bad.step_mpa = -1.0;
        encode(&bad, &mut blob).unwrap();
        assert!(matches!(decode::<4, 2>(&blob), Err(Error::OutOfRange(..))));
        // The paper model's blob reader refuses it too (another magic).
        encode(&table(), &mut blob).unwrap();
        assert!(crate::blob::decode_model(&blob).is_err());
    }
}
