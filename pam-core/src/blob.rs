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
//!
//! # Version 2: the model with its effects
//!
//! Version 2 carries the same 14 parameters and the effects the model has
//! (the paper's future work, [`crate::effects`]), [`BLOB_V2_LEN`] bytes:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"PAMC"` |
//! | 4 | 2 | format version ([`BLOB_VERSION_V2`]) |
//! | 6 | 2 | payload length in bytes ([`PAYLOAD_V2_LEN`]) |
//! | 8 | 56 | the 14 `f32` fields of [`Params`], in declaration order |
//! | 64 | 4 | effect flags, `u32`: [`FLAG_MEMORY`], [`FLAG_RATE`], [`FLAG_CREEP`], [`FLAG_WIDTH`], [`FLAG_SHAPE`]; any other bit set is refused |
//! | 68 | 8 | non-local memory: `shape`, `merge_span` |
//! | 76 | 16 | rate dependence: `scale_at_rest`, `scale_per_mpa_per_s`, `exponent`, `filter_time_s` |
//! | 92 | 8 | creep: `gain`, `time_constant_s` |
//! | 100 | 8 | load-dependent width: `scale_at_min_load`, `scale_per_step` |
//! | 108 | 16 | constraint shape: `bulge`, `tilt`, `bulge_per_step`, `tilt_per_step` |
//! | 124 | 4 | rate dependence: `max_rate_mpa_per_s` (the saturation rate) |
//! | 128 | 24 | constraint shape: `root_shift`, `end_shift`, `root_shift_per_step`, `end_shift_per_step`, `root_shift_per_step_sq`, `end_shift_per_step_sq` |
//! | 152 | 4 | CRC-32 of bytes 0..152 |
//!
//! # Version 3: a constraint shape with its stroke table
//!
//! Version 2's layout with the payload extended by the shape's stroke table
//! ([`crate::effects::shape::StrokeTable`]: [`TABLE_FIELDS`] = 66 `f32`
//! knots, load by load), [`BLOB_V3_LEN`] = 420 bytes: bytes 0..152 as
//! version 2 (version field 3, payload length [`PAYLOAD_V3_LEN`]), 152..416
//! the knots, 416..420 the CRC-32 of bytes 0..416. Written only for a shape whose table is not the
//! identity ([`encode_model`] picks the version), so every model has one
//! encoding; a version-3 blob without a shape or with the identity table is
//! refused.
//!
//! # Version 4: a model with a pressure lag
//!
//! Version 3's layout (the stroke table's knots are the identity's when the
//! model has none) with the payload extended by the pressure lag's time
//! constant ([`crate::effects::PressureLag`], flag [`FLAG_PRESSURE_LAG`]),
//! [`BLOB_V4_LEN`] = 424 bytes: bytes 0..416 as version 3 (version field
//! 4, payload length [`PAYLOAD_V4_LEN`]), 416..420 `time_constant_s`,
//! 420..424 the CRC-32 of bytes 0..420. Written only for a model with the
//! lag; the lag's flag in a version 2 or 3 blob, or its absence in a
//! version 4 one, is refused.
//!
//! # Version 5: a model with a pressure delay
//!
//! Version 4's layout (the lag's time constant 0 and its flag clear when
//! the model has no lag) with the payload extended by the pressure delay
//! ([`crate::effects::PressureDelay`], flag [`FLAG_PRESSURE_DELAY`]),
//! [`BLOB_V5_LEN`] = 428 bytes: bytes 0..420 as version 4 (version field
//! 5, payload length [`PAYLOAD_V5_LEN`]), 420..424 `delay_s`, 424..428 the
//! CRC-32 of bytes 0..424. Written only for a model with the delay; the
//! delay's flag in an earlier version, or its absence in version 5, is
//! refused.
//!
//! An effect whose flag is clear has its fields written as zeros, and they
//! must be zero to decode (one encoding per model). [`decode_model`] reads
//! both versions (version 1: no effects), checks framing and CRC and
//! validates the parameters and the effects; a reader that cannot run an
//! effect refuses the blob (the firmware runs the memory only).

use crate::coeffs::Coeffs;
use crate::effects::shape::table::{TABLE_KNOTS, TABLE_LOADS};
use crate::effects::shape::StrokeTable;
use crate::effects::{
    ConstraintShape, Creep, Effects, LoadDependentWidth, NonLocalMemory, PressureDelay,
    PressureLag, RateDependence,
};
use crate::error::Error;
use crate::params::{CriticalPoints, Params, Point};

/// Magic bytes at the start of a blob.
pub const BLOB_MAGIC: [u8; 4] = *b"PAMC";
/// Format version 1 (the paper's parameters only), which [`encode`] writes
/// and [`decode`] reads.
pub const BLOB_VERSION: u16 = 1;
/// Format version 2 (parameters and effects), which [`encode_v2`] writes;
/// [`decode_model`] reads both.
pub const BLOB_VERSION_V2: u16 = 2;
/// Effect flag: non-local memory.
pub const FLAG_MEMORY: u32 = 1 << 0;
/// Effect flag: rate dependence.
pub const FLAG_RATE: u32 = 1 << 1;
/// Effect flag: creep.
pub const FLAG_CREEP: u32 = 1 << 2;
/// Effect flag: load-dependent width.
pub const FLAG_WIDTH: u32 = 1 << 3;
/// Effect flag: the constraint-shape correction.
pub const FLAG_SHAPE: u32 = 1 << 4;
/// Effect flag: the pressure lag (version 4 only).
pub const FLAG_PRESSURE_LAG: u32 = 1 << 5;
/// Effect flag: the pressure delay (version 5 only).
pub const FLAG_PRESSURE_DELAY: u32 = 1 << 6;
/// Every flag this crate knows.
pub const KNOWN_FLAGS: u32 = FLAG_MEMORY
    | FLAG_RATE
    | FLAG_CREEP
    | FLAG_WIDTH
    | FLAG_SHAPE
    | FLAG_PRESSURE_LAG
    | FLAG_PRESSURE_DELAY;
/// `f32` fields of the effects in a version-2 payload.
pub const EFFECT_FIELDS: usize = 21;
/// Version-2 payload length, bytes: parameters, flags, effect fields.
pub const PAYLOAD_V2_LEN: usize = 4 * PAYLOAD_FIELDS + 4 + 4 * EFFECT_FIELDS;
/// Version-2 blob length, bytes.
pub const BLOB_V2_LEN: usize = 8 + PAYLOAD_V2_LEN + 4;
/// Format version 3 (version 2 and the shape's stroke table).
pub const BLOB_VERSION_V3: u16 = 3;
/// `f32` fields of the stroke table in a version-3 payload.
pub const TABLE_FIELDS: usize = TABLE_LOADS * TABLE_KNOTS;
/// Version-3 payload length, bytes.
pub const PAYLOAD_V3_LEN: usize = PAYLOAD_V2_LEN + 4 * TABLE_FIELDS;
/// Version-3 blob length, bytes.
pub const BLOB_V3_LEN: usize = 8 + PAYLOAD_V3_LEN + 4;
/// Format version 4 (version 3 and the pressure lag).
pub const BLOB_VERSION_V4: u16 = 4;
/// Version-4 payload length, bytes.
pub const PAYLOAD_V4_LEN: usize = PAYLOAD_V3_LEN + 4;
/// Version-4 blob length, bytes.
pub const BLOB_V4_LEN: usize = 8 + PAYLOAD_V4_LEN + 4;
/// Format version 5 (version 4 and the pressure delay).
pub const BLOB_VERSION_V5: u16 = 5;
/// Version-5 payload length, bytes.
pub const PAYLOAD_V5_LEN: usize = PAYLOAD_V4_LEN + 4;
/// Version-5 blob length, bytes.
pub const BLOB_V5_LEN: usize = 8 + PAYLOAD_V5_LEN + 4;
/// The longest blob of any version this crate reads, bytes.
pub const MAX_BLOB_LEN: usize = BLOB_V5_LEN;
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
    let body = checked_body(bytes, PAYLOAD_LEN)?;
    let mut f = [0f32; PAYLOAD_FIELDS];
    for (v, chunk) in f.iter_mut().zip(bytes[8..body].chunks_exact(4)) {
        *v = f32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
    }
    Ok(from_fields(&f))
}

/// The framing both versions share after magic and version: the blob is
/// exactly header, `payload_len` bytes and CRC long, its header says
/// `payload_len`, and the CRC matches. Returns where the payload ends.
fn checked_body(bytes: &[u8], payload_len: usize) -> Result<usize, Error> {
    let body = 8 + payload_len;
    if bytes.len() != body + 4 {
        return Err(Error::Blob("wrong length"));
    }
    if usize::from(u16::from_le_bytes([bytes[6], bytes[7]])) != payload_len {
        return Err(Error::Blob("wrong payload length"));
    }
    let stored = u32::from_le_bytes([
        bytes[body],
        bytes[body + 1],
        bytes[body + 2],
        bytes[body + 3],
    ]);
    if crc32(&bytes[..body]) != stored {
        return Err(Error::Blob("CRC mismatch"));
    }
    Ok(body)
}

/// Where each effect's fields sit in the version-2 field array, in the
/// order of its struct's fields: the layout, written once (the rate's
/// saturation and the shape's shifts came later, after the first fields).
const MEMORY_AT: [usize; 2] = [0, 1];
const RATE_AT: [usize; 5] = [2, 3, 4, 5, 14];
const CREEP_AT: [usize; 2] = [6, 7];
const WIDTH_AT: [usize; 2] = [8, 9];
const SHAPE_AT: [usize; 10] = [10, 11, 12, 13, 15, 16, 17, 18, 19, 20];

/// `values` into `f` at `at`.
fn scatter<const N: usize>(f: &mut [f32; EFFECT_FIELDS], at: [usize; N], values: [f32; N]) {
    for (i, v) in at.into_iter().zip(values) {
        if let Some(slot) = f.get_mut(i) {
            *slot = v;
        }
    }
}

/// The fields of `f` at `at`.
fn gather<const N: usize>(f: &[f32; EFFECT_FIELDS], at: [usize; N]) -> [f32; N] {
    at.map(|i| f.get(i).copied().unwrap_or(0.0))
}

/// The effect flags and fields of `e`, in the version-2 layout.
fn effect_fields(e: &Effects) -> (u32, [f32; EFFECT_FIELDS]) {
    let mut flags = 0;
    let mut f = [0.0f32; EFFECT_FIELDS];
    if let Some(m) = e.memory {
        flags |= FLAG_MEMORY;
        scatter(&mut f, MEMORY_AT, [m.shape, m.merge_span]);
    }
    if let Some(r) = e.rate {
        flags |= FLAG_RATE;
        let v = [
            r.scale_at_rest,
            r.scale_per_mpa_per_s,
            r.exponent,
            r.filter_time_s,
            r.max_rate_mpa_per_s,
        ];
        scatter(&mut f, RATE_AT, v);
    }
    if let Some(c) = e.creep {
        flags |= FLAG_CREEP;
        scatter(&mut f, CREEP_AT, [c.gain, c.time_constant_s]);
    }
    if let Some(w) = e.width {
        flags |= FLAG_WIDTH;
        scatter(&mut f, WIDTH_AT, [w.scale_at_min_load, w.scale_per_step]);
    }
    if let Some(c) = e.shape {
        flags |= FLAG_SHAPE;
        let v = [
            c.bulge,
            c.tilt,
            c.bulge_per_step,
            c.tilt_per_step,
            c.root_shift,
            c.end_shift,
            c.root_shift_per_step,
            c.end_shift_per_step,
            c.root_shift_per_step_sq,
            c.end_shift_per_step_sq,
        ];
        scatter(&mut f, SHAPE_AT, v);
    }
    if e.pressure_lag.is_some() {
        flags |= FLAG_PRESSURE_LAG;
    }
    if e.pressure_delay.is_some() {
        flags |= FLAG_PRESSURE_DELAY;
    }
    (flags, f)
}

/// The effects of version-2 flags and fields; fields of an absent effect
/// must be zero.
fn effects_from(flags: u32, f: &[f32; EFFECT_FIELDS]) -> Result<Effects, Error> {
    if flags & !KNOWN_FLAGS != 0 {
        return Err(Error::Blob("unknown effect flags"));
    }
    let on = |flag: u32, fields: &[f32]| -> Result<bool, Error> {
        let present = flags & flag != 0;
        if !present && fields.iter().any(|v| v.to_bits() != 0) {
            return Err(Error::Blob("fields of an absent effect are not zero"));
        }
        Ok(present)
    };
    let [shape, merge_span] = gather(f, MEMORY_AT);
    let [scale_at_rest, scale_per_mpa_per_s, exponent, filter_time_s, max_rate_mpa_per_s] =
        gather(f, RATE_AT);
    let [gain, time_constant_s] = gather(f, CREEP_AT);
    let [scale_at_min_load, scale_per_step] = gather(f, WIDTH_AT);
    let s = gather(f, SHAPE_AT);
    let e = Effects {
        memory: on(FLAG_MEMORY, &gather(f, MEMORY_AT))?
            .then_some(NonLocalMemory { shape, merge_span }),
        rate: on(FLAG_RATE, &gather(f, RATE_AT))?.then_some(RateDependence {
            scale_at_rest,
            scale_per_mpa_per_s,
            exponent,
            filter_time_s,
            max_rate_mpa_per_s,
        }),
        creep: on(FLAG_CREEP, &gather(f, CREEP_AT))?.then_some(Creep {
            gain,
            time_constant_s,
        }),
        width: on(FLAG_WIDTH, &gather(f, WIDTH_AT))?.then_some(LoadDependentWidth {
            scale_at_min_load,
            scale_per_step,
        }),
        shape: on(FLAG_SHAPE, &s)?.then_some(ConstraintShape {
            bulge: s[0],
            tilt: s[1],
            bulge_per_step: s[2],
            tilt_per_step: s[3],
            root_shift: s[4],
            end_shift: s[5],
            root_shift_per_step: s[6],
            end_shift_per_step: s[7],
            root_shift_per_step_sq: s[8],
            end_shift_per_step_sq: s[9],
            table: StrokeTable::NEUTRAL,
        }),
        // Their fields are after the table (versions 4 and 5): read there.
        pressure_lag: None,
        pressure_delay: None,
    };
    Ok(e)
}

/// Write the version-2 part (header for `version` and `payload_len`,
/// parameters, flags, effect fields) into `out`; returns where it ends.
fn write_v2_part(
    out: &mut [u8],
    params: &Params,
    effects: &Effects,
    version: u16,
    payload_len: usize,
) -> usize {
    out[0..4].copy_from_slice(&BLOB_MAGIC);
    out[4..6].copy_from_slice(&version.to_le_bytes());
    out[6..8].copy_from_slice(&(payload_len as u16).to_le_bytes());
    let (flags, ef) = effect_fields(effects);
    let p_end = 8 + PAYLOAD_LEN;
    for (chunk, v) in out[8..p_end].chunks_exact_mut(4).zip(fields(params)) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    out[p_end..p_end + 4].copy_from_slice(&flags.to_le_bytes());
    let end = 8 + PAYLOAD_V2_LEN;
    for (chunk, v) in out[p_end + 4..end].chunks_exact_mut(4).zip(ef) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    end
}

/// Encode `params` and `effects` in format version 2 (not validated here:
/// validate with [`Coeffs::new`] and [`Effects::validate`] first). A shape's
/// stroke table is not in version 2: [`encode_model`] picks the version.
pub fn encode_v2(params: &Params, effects: &Effects) -> [u8; BLOB_V2_LEN] {
    let mut out = [0u8; BLOB_V2_LEN];
    let body = write_v2_part(&mut out, params, effects, BLOB_VERSION_V2, PAYLOAD_V2_LEN);
    seal(&mut out, body);
    out
}

/// Write the CRC-32 of `out[..body]` after it (the blob's last 4 bytes).
fn seal(out: &mut [u8], body: usize) {
    let crc = crc32(&out[..body]);
    out[body..body + 4].copy_from_slice(&crc.to_le_bytes());
}

/// Encode `params` and `effects` in format version 3: version 2 and the
/// shape's stroke table (identity knots without a shape).
pub fn encode_v3(params: &Params, effects: &Effects) -> [u8; BLOB_V3_LEN] {
    let mut out = [0u8; BLOB_V3_LEN];
    let at = write_v3_part(&mut out, params, effects, BLOB_VERSION_V3, PAYLOAD_V3_LEN);
    seal(&mut out, at);
    out
}

/// Write the version-3 part (the version-2 part and the stroke table's
/// knots, the identity's without a table) into `out`; returns where it
/// ends.
fn write_v3_part(
    out: &mut [u8],
    params: &Params,
    effects: &Effects,
    version: u16,
    payload_len: usize,
) -> usize {
    let mut at = write_v2_part(out, params, effects, version, payload_len);
    let table = effects.shape.map_or(StrokeTable::NEUTRAL, |s| s.table);
    for v in table.knots.iter().flatten() {
        out[at..at + 4].copy_from_slice(&v.to_le_bytes());
        at += 4;
    }
    at
}

/// Encode `params` and `effects` in format version 4: version 3 and the
/// pressure lag's time constant (0 without the lag, which
/// [`encode_model`] never writes in this version).
pub fn encode_v4(params: &Params, effects: &Effects) -> [u8; BLOB_V4_LEN] {
    let mut out = [0u8; BLOB_V4_LEN];
    let at = write_v4_part(&mut out, params, effects, BLOB_VERSION_V4, PAYLOAD_V4_LEN);
    seal(&mut out, at);
    out
}

/// Write the version-4 part (the version-3 part and the lag's time
/// constant, 0 without the lag) into `out`; returns where it ends.
fn write_v4_part(
    out: &mut [u8],
    params: &Params,
    effects: &Effects,
    version: u16,
    payload_len: usize,
) -> usize {
    let at = write_v3_part(out, params, effects, version, payload_len);
    let tau = effects.pressure_lag.map_or(0.0, |l| l.time_constant_s);
    out[at..at + 4].copy_from_slice(&tau.to_le_bytes());
    at + 4
}

/// Encode `params` and `effects` in format version 5: version 4 and the
/// pressure delay (0 without it, which [`encode_model`] never writes in
/// this version).
pub fn encode_v5(params: &Params, effects: &Effects) -> [u8; BLOB_V5_LEN] {
    let mut out = [0u8; BLOB_V5_LEN];
    let mut at = write_v4_part(&mut out, params, effects, BLOB_VERSION_V5, PAYLOAD_V5_LEN);
    let d = effects.pressure_delay.map_or(0.0, |d| d.delay_s);
    out[at..at + 4].copy_from_slice(&d.to_le_bytes());
    at += 4;
    seal(&mut out, at);
    out
}

/// The blob of a model in the first version that holds it: version 1
/// without effects, version 2 with effects, version 3 with a shape whose
/// stroke table is not the identity, version 4 with the pressure lag,
/// version 5 with the pressure delay. The bytes and their length.
pub fn encode_model(params: &Params, effects: &Effects) -> ([u8; MAX_BLOB_LEN], usize) {
    let mut out = [0u8; MAX_BLOB_LEN];
    let len = if *effects == Effects::NONE {
        out[..BLOB_LEN].copy_from_slice(&encode(params));
        BLOB_LEN
    } else if effects.pressure_delay.is_some() {
        out[..BLOB_V5_LEN].copy_from_slice(&encode_v5(params, effects));
        BLOB_V5_LEN
    } else if effects.pressure_lag.is_some() {
        out[..BLOB_V4_LEN].copy_from_slice(&encode_v4(params, effects));
        BLOB_V4_LEN
    } else if effects.shape.is_some_and(|s| !s.table.is_neutral()) {
        out[..BLOB_V3_LEN].copy_from_slice(&encode_v3(params, effects));
        BLOB_V3_LEN
    } else {
        out[..BLOB_V2_LEN].copy_from_slice(&encode_v2(params, effects));
        BLOB_V2_LEN
    };
    (out, len)
}

/// Length of the blob framed at the start of `bytes` (its header's payload
/// length plus header and CRC), for a blob stored in a larger region; `None`
/// without a blob's magic and version there.
pub fn framed_len(bytes: &[u8]) -> Option<usize> {
    let head = bytes.get(0..8)?;
    if head[0..4] != BLOB_MAGIC {
        return None;
    }
    let version = u16::from_le_bytes([head[4], head[5]]);
    if !matches!(
        version,
        BLOB_VERSION | BLOB_VERSION_V2 | BLOB_VERSION_V3 | BLOB_VERSION_V4 | BLOB_VERSION_V5
    ) {
        return None;
    }
    let len = 8 + usize::from(u16::from_le_bytes([head[6], head[7]])) + 4;
    (len <= bytes.len()).then_some(len)
}

/// Decode a blob of either version to its parameters and effects, checking
/// framing and CRC only.
pub fn decode_model_params(bytes: &[u8]) -> Result<(Params, Effects), Error> {
    if bytes.len() < 8 || bytes[0..4] != BLOB_MAGIC {
        return Err(Error::Blob("bad magic"));
    }
    match u16::from_le_bytes([bytes[4], bytes[5]]) {
        BLOB_VERSION => decode_params(bytes).map(|p| (p, Effects::NONE)),
        version @ (BLOB_VERSION_V2 | BLOB_VERSION_V3 | BLOB_VERSION_V4 | BLOB_VERSION_V5) => {
            let v5 = version == BLOB_VERSION_V5;
            let v4 = version == BLOB_VERSION_V4;
            let v3 = version == BLOB_VERSION_V3;
            checked_body(
                bytes,
                match version {
                    BLOB_VERSION_V2 => PAYLOAD_V2_LEN,
                    BLOB_VERSION_V3 => PAYLOAD_V3_LEN,
                    BLOB_VERSION_V4 => PAYLOAD_V4_LEN,
                    _ => PAYLOAD_V5_LEN,
                },
            )?;
            let word = |i: usize| [bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]];
            let mut f = [0f32; PAYLOAD_FIELDS];
            for (k, v) in f.iter_mut().enumerate() {
                *v = f32::from_le_bytes(word(8 + 4 * k));
            }
            let p_end = 8 + PAYLOAD_LEN;
            let flags = u32::from_le_bytes(word(p_end));
            let mut ef = [0f32; EFFECT_FIELDS];
            for (k, v) in ef.iter_mut().enumerate() {
                *v = f32::from_le_bytes(word(p_end + 4 + 4 * k));
            }
            let mut effects = effects_from(flags, &ef)?;
            let lag = flags & FLAG_PRESSURE_LAG != 0;
            if lag != v4 && !(v5 && lag) {
                return Err(Error::Blob(
                    "the pressure lag's flag is set in every version-4 blob and only in versions 4 and 5",
                ));
            }
            if (flags & FLAG_PRESSURE_DELAY != 0) != v5 {
                return Err(Error::Blob(
                    "the pressure delay's flag is set exactly in a version-5 blob",
                ));
            }
            if v3 || v4 || v5 {
                let mut table = StrokeTable::NEUTRAL;
                let mut at = 8 + PAYLOAD_V2_LEN;
                for v in table.knots.iter_mut().flatten() {
                    *v = f32::from_le_bytes(word(at));
                    at += 4;
                }
                match effects.shape.as_mut() {
                    Some(shape) if !table.is_neutral() => shape.table = table,
                    // Versions 4 and 5 hold the identity's knots without a table.
                    _ if (v4 || v5) && table.is_neutral() => {}
                    _ => {
                        return Err(Error::Blob(
                            "a version-3 blob without a shape's stroke table (write version 2)",
                        ))
                    }
                }
                if v4 || v5 {
                    let tau = f32::from_le_bytes(word(at));
                    at += 4;
                    if lag {
                        effects.pressure_lag = Some(PressureLag {
                            time_constant_s: tau,
                        });
                    } else if tau.to_bits() != 0 {
                        return Err(Error::Blob("fields of an absent effect are not zero"));
                    }
                }
                if v5 {
                    effects.pressure_delay = Some(PressureDelay {
                        delay_s: f32::from_le_bytes(word(at)),
                    });
                }
            }
            Ok((from_fields(&f), effects))
        }
        _ => Err(Error::Blob("unsupported version")),
    }
}

/// Decode and validate a blob of either version: the coefficients and the
/// effects (none for version 1). Any defect is an [`Error::Blob`], the
/// validation error of [`Coeffs::new`] or of [`Effects::validate`].
///
/// ```
/// use pam_core::blob::{decode_model, encode, encode_v2};
/// use pam_core::effects::NonLocalMemory;
/// use pam_core::{Effects, Params};
///
/// let with_memory = Effects {
///     memory: Some(NonLocalMemory { shape: 1.0, merge_span: 0.1 }),
///     ..Effects::NONE
/// };
/// let (c, e) = decode_model(&encode_v2(&Params::DEFAULT, &with_memory)).unwrap();
/// assert_eq!((c.params(), e), (&Params::DEFAULT, with_memory));
/// // Version 1 is still read: the paper's model, no effects.
/// let (_, e) = decode_model(&encode(&Params::DEFAULT)).unwrap();
/// assert_eq!(e, Effects::NONE);
/// ```
pub fn decode_model(bytes: &[u8]) -> Result<(Coeffs, Effects), Error> {
    let (params, effects) = decode_model_params(bytes)?;
    let coeffs = Coeffs::new(params)?;
    effects.validate()?;
    Ok((coeffs, effects))
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

    fn with_a_table() -> Effects {
        let mut table = StrokeTable::NEUTRAL;
        for (i, node) in table.knots.iter_mut().enumerate() {
            for (j, v) in node.iter_mut().enumerate() {
                let u = (j + 1) as f32 / crate::effects::shape::table::TABLE_SEGMENTS as f32;
                *v = u + 0.1 * (i as f32 + 1.0) * u * (1.0 - u);
            }
        }
        Effects {
            shape: Some(ConstraintShape {
                bulge: 0.1,
                table,
                ..ConstraintShape::NEUTRAL
            }),
            ..Effects::NONE
        }
    }

    #[test]
    fn encode_model_picks_the_first_version_that_holds_the_model() {
        let p = Params::DEFAULT;
        let (b, n) = encode_model(&p, &Effects::NONE);
        assert_eq!(&b[..n], &encode(&p)[..]);
        let plain_shape = Effects {
            shape: Some(ConstraintShape {
                bulge: 0.1,
                ..ConstraintShape::NEUTRAL
            }),
            ..Effects::NONE
        };
        let (b, n) = encode_model(&p, &plain_shape);
        assert_eq!(&b[..n], &encode_v2(&p, &plain_shape)[..]);
        let e = with_a_table();
        let (b, n) = encode_model(&p, &e);
        assert_eq!(n, BLOB_V3_LEN);
        let (c, back) = decode_model(&b[..n]).unwrap();
        assert_eq!((c.params(), back), (&p, e));
        assert_eq!(framed_len(&b), Some(BLOB_V3_LEN));
    }

    /// `encode_model` writes `len` bytes for `p` with `e`, they decode to
    /// the same model, and flipping any seventh bit is refused.
    fn round_trips_and_refuses_every_flip(p: &Params, e: &Effects, len: usize) {
        let (b, n) = encode_model(p, e);
        assert_eq!(n, len);
        assert_eq!(framed_len(&b), Some(len));
        let (c, back) = decode_model(&b[..n]).unwrap();
        assert_eq!((c.params(), &back), (p, e));
        for i in (0..len * 8).step_by(7) {
            let mut x = b;
            x[i / 8] ^= 1 << (i % 8);
            assert!(decode_model(&x[..n]).is_err(), "bit {i}");
        }
    }

    #[test]
    fn a_model_with_a_pressure_lag_is_version_4_with_or_without_a_table() {
        let p = Params::DEFAULT;
        let lag = Some(PressureLag {
            time_constant_s: 0.015,
        });
        for e in [
            Effects {
                pressure_lag: lag,
                ..Effects::NONE
            },
            Effects {
                pressure_lag: lag,
                ..with_a_table()
            },
            Effects {
                pressure_lag: lag,
                ..with_every_effect()
            },
        ] {
            round_trips_and_refuses_every_flip(&p, &e, BLOB_V4_LEN);
        }
        // Without the lag version 4 is refused (one encoding per model), and
        // so is a time constant out of range.
        assert!(decode_model(&encode_v4(&p, &with_a_table())).is_err());
        let bad = Effects {
            pressure_lag: Some(PressureLag {
                time_constant_s: 2.0,
            }),
            ..Effects::NONE
        };
        assert!(decode_model(&encode_v4(&p, &bad)).is_err());
    }

    #[test]
    fn a_model_with_a_pressure_delay_is_version_5_with_or_without_a_lag() {
        let p = Params::DEFAULT;
        let delay = Some(PressureDelay { delay_s: 0.006 });
        let lag = Some(PressureLag {
            time_constant_s: 0.015,
        });
        for e in [
            Effects {
                pressure_delay: delay,
                ..Effects::NONE
            },
            Effects {
                pressure_delay: delay,
                ..with_a_table()
            },
            Effects {
                pressure_delay: delay,
                pressure_lag: lag,
                ..with_every_effect()
            },
        ] {
            round_trips_and_refuses_every_flip(&p, &e, BLOB_V5_LEN);
        }
        // Without the delay version 5 is refused (one encoding per model);
        // so are the delay's flag in version 4, a delay out of range, and a
        // lag's time constant written without its flag.
        assert!(decode_model(&encode_v5(&p, &with_a_table())).is_err());
        let both = Effects {
            pressure_delay: delay,
            pressure_lag: lag,
            ..Effects::NONE
        };
        assert!(decode_model(&encode_v4(&p, &both)).is_err());
        let bad = Effects {
            pressure_delay: Some(PressureDelay { delay_s: 0.5 }),
            ..Effects::NONE
        };
        assert!(decode_model(&encode_v5(&p, &bad)).is_err());
        let mut b = encode_v5(&p, &both);
        let flags_at = 8 + PAYLOAD_LEN;
        let flags = u32::from_le_bytes([
            b[flags_at],
            b[flags_at + 1],
            b[flags_at + 2],
            b[flags_at + 3],
        ]) & !FLAG_PRESSURE_LAG;
        b[flags_at..flags_at + 4].copy_from_slice(&flags.to_le_bytes());
        let body = BLOB_V5_LEN - 4;
        seal(&mut b, body);
        assert_eq!(
            decode_model(&b),
            Err(Error::Blob("fields of an absent effect are not zero"))
        );
    }

    #[test]
    fn a_version_3_blob_is_checked_like_the_others() {
        let p = Params::DEFAULT;
        let blob = encode_v3(&p, &with_a_table());
        for i in 0..BLOB_V3_LEN * 8 {
            let mut b = blob;
            b[i / 8] ^= 1 << (i % 8);
            assert!(decode_model(&b).is_err(), "bit {i}");
        }
        // The identity table is version 2's: one encoding per model.
        let plain = Effects {
            shape: Some(ConstraintShape::NEUTRAL),
            ..Effects::NONE
        };
        assert!(decode_model(&encode_v3(&p, &plain)).is_err());
        assert!(decode_model(&encode_v3(&p, &Effects::NONE)).is_err());
        // A falling table is refused by the shape's validation.
        let mut e = with_a_table();
        if let Some(s) = e.shape.as_mut() {
            s.table.knots[1][2] = s.table.knots[1][1];
        }
        assert!(decode_model(&encode_v3(&p, &e)).is_err());
    }

    fn with_every_effect() -> Effects {
        Effects {
            memory: Some(NonLocalMemory {
                shape: 1.5,
                merge_span: 0.11,
            }),
            rate: Some(RateDependence {
                scale_at_rest: 1.0,
                scale_per_mpa_per_s: 0.8,
                exponent: 0.5,
                filter_time_s: 0.19,
                max_rate_mpa_per_s: 0.3,
            }),
            creep: Some(Creep {
                gain: 0.2,
                time_constant_s: 1.5,
            }),
            width: Some(LoadDependentWidth {
                scale_at_min_load: 0.8,
                scale_per_step: 0.1,
            }),
            shape: Some(ConstraintShape {
                bulge: 0.1,
                tilt: -0.05,
                bulge_per_step: 0.02,
                tilt_per_step: 0.01,
                root_shift: 0.01,
                end_shift: -0.02,
                root_shift_per_step: 0.005,
                end_shift_per_step: -0.006,
                root_shift_per_step_sq: 0.003,
                end_shift_per_step_sq: -0.004,
                table: StrokeTable::NEUTRAL,
            }),
            pressure_lag: None,
            pressure_delay: None,
        }
    }

    #[test]
    fn v2_round_trips_every_combination_of_effects() {
        let all = with_every_effect();
        for mask in 0..32u32 {
            let e = Effects {
                memory: all.memory.filter(|_| mask & FLAG_MEMORY != 0),
                rate: all.rate.filter(|_| mask & FLAG_RATE != 0),
                creep: all.creep.filter(|_| mask & FLAG_CREEP != 0),
                width: all.width.filter(|_| mask & FLAG_WIDTH != 0),
                shape: all.shape.filter(|_| mask & FLAG_SHAPE != 0),
                pressure_lag: None,
                pressure_delay: None,
            };
            let blob = encode_v2(&Params::DEFAULT, &e);
            assert_eq!(
                u32::from_le_bytes([blob[64], blob[65], blob[66], blob[67]]),
                mask
            );
            let (c, back) = decode_model(&blob).unwrap();
            assert_eq!(c.params(), &Params::DEFAULT);
            assert_eq!(back, e);
            assert_eq!(
                framed_len(&[&blob[..], &[0xFF; 7]].concat()),
                Some(BLOB_V2_LEN)
            );
        }
    }

    #[test]
    fn v1_is_still_read_as_a_model_without_effects() {
        let blob = encode(&Params::DEFAULT);
        let (c, e) = decode_model(&blob).unwrap();
        assert_eq!(c.params(), &Params::DEFAULT);
        assert_eq!(e, Effects::NONE);
        assert_eq!(framed_len(&blob), Some(BLOB_LEN));
        // And `decode` (version 1 only) refuses a version-2 blob.
        let v2 = encode_v2(&Params::DEFAULT, &Effects::NONE);
        assert_eq!(decode(&v2), Err(Error::Blob("wrong length")));
    }

    #[test]
    fn every_single_bit_flip_of_a_v2_blob_is_refused() {
        let blob = encode_v2(&Params::DEFAULT, &with_every_effect());
        for i in 0..BLOB_V2_LEN * 8 {
            let mut b = blob;
            b[i / 8] ^= 1 << (i % 8);
            assert!(decode_model(&b).is_err(), "bit {i}");
        }
    }

    /// Re-frame a version-2 blob after editing its body.
    fn refresh_crc(b: &mut [u8; BLOB_V2_LEN]) {
        let body = 8 + PAYLOAD_V2_LEN;
        let crc = crc32(&b[..body]);
        b[body..].copy_from_slice(&crc.to_le_bytes());
    }

    #[test]
    fn unknown_flags_stray_fields_and_invalid_effects_are_refused() {
        let mut b = encode_v2(&Params::DEFAULT, &Effects::NONE);
        b[64] = 1 << 7;
        refresh_crc(&mut b);
        assert_eq!(decode_model(&b), Err(Error::Blob("unknown effect flags")));
        // The pressure delay's flag without its field (version 5's).
        let mut b = encode_v2(&Params::DEFAULT, &Effects::NONE);
        b[64] = 1 << 6;
        refresh_crc(&mut b);
        assert_eq!(
            decode_model(&b),
            Err(Error::Blob(
                "the pressure delay's flag is set exactly in a version-5 blob"
            ))
        );
        // The pressure lag's flag without its field (version 4's).
        let mut b = encode_v2(&Params::DEFAULT, &Effects::NONE);
        b[64] = 1 << 5;
        refresh_crc(&mut b);
        assert_eq!(
            decode_model(&b),
            Err(Error::Blob(
                "the pressure lag's flag is set in every version-4 blob and only in versions 4 and 5"
            ))
        );
        let mut b = encode_v2(&Params::DEFAULT, &Effects::NONE);
        b[70] = 0x3F; // a memory field without the memory flag
        refresh_crc(&mut b);
        assert_eq!(
            decode_model(&b),
            Err(Error::Blob("fields of an absent effect are not zero"))
        );
        let bad = Effects {
            memory: Some(NonLocalMemory {
                shape: 99.0,
                merge_span: 1.0,
            }),
            ..Effects::NONE
        };
        assert!(matches!(
            decode_model(&encode_v2(&Params::DEFAULT, &bad)),
            Err(Error::OutOfRange("memory.shape", _))
        ));
        let mut b = encode_v2(&Params::DEFAULT, &Effects::NONE);
        b[4] = 9;
        assert_eq!(decode_model(&b), Err(Error::Blob("unsupported version")));
        assert_eq!(framed_len(&b), None);
    }

    #[test]
    fn each_effect_field_has_one_place_in_the_layout() {
        // Every index of the version-2 field array belongs to exactly one
        // effect's field.
        let mut seen = [0u8; EFFECT_FIELDS];
        let all: [&[usize]; 5] = [&MEMORY_AT, &RATE_AT, &CREEP_AT, &WIDTH_AT, &SHAPE_AT];
        for at in all {
            for &i in at {
                seen[i] += 1;
            }
        }
        assert_eq!(seen, [1u8; EFFECT_FIELDS]);
    }
}
