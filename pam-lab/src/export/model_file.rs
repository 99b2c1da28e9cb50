//! Model files: the JSON model (units in the keys), the firmware's coefficient
//! blob (`pam_core::blob`: magic, version, CRC-32), and a Rust source file of
//! constants — for the paper's model and for a model with effects
//! ([`model_files`]: JSON version 2 with an `effects` object, blob
//! version 2, an `EFFECTS` constant).

use std::path::Path;

use anyhow::{bail, Context, Result};
use pam_core::effects::ConstraintShape;
use pam_core::{blob, Coeffs, Effects, Params};
use serde::{Deserialize, Serialize};

use crate::evaluate::errors::ErrorTable;

/// Format tag of the JSON model file.
pub const FORMAT: &str = "pam-lab model";
/// Version of the JSON model file of the paper's model (no effects).
pub const VERSION: u32 = 1;
/// Version of the JSON model file of a model with effects (the `effects`
/// key); [`load`] reads both.
pub const VERSION_EFFECTS: u32 = 2;

/// How a model was fitted: enough to reproduce it and judge it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitSummary {
    /// The record the model was fitted to.
    pub source: String,
    /// Samples in the record.
    pub samples: usize,
    /// Samples the fit used.
    pub training_samples: usize,
    /// The hold-out rule (`every:K`, `tail:F`, `none`).
    pub holdout: String,
    /// Whether `Pmax` was `measured` or `given`.
    pub max_pressure_source: String,
    /// Estimated pressure noise of the record, MPa.
    pub pressure_noise_mpa: f64,
    /// Estimated contraction noise of the record (fraction of rest length).
    pub contraction_noise: f64,
    /// Errors on the held-out samples, per load bin and branch.
    pub heldout_errors: Option<ErrorTable>,
    /// The reference surface's RMS pressure error on the same held-out
    /// samples (`pam_lab::identify::reference`), MPa.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_heldout_rms_mpa: Option<f64>,
    /// The model and the reference surface on a record neither was fitted
    /// to (`--validate`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation: Option<crate::identify::fit::Validation>,
    /// The model's errors per part of the record fitted (its `# segment`
    /// seams); absent for a record of one run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub segments: Vec<crate::evaluate::segments::SegmentErrors>,
}

/// The JSON model file. `params` is pam-core's [`Params`], whose keys carry
/// their units (`_n` newtons, `_mpa` MPa; contractions are fractions of the
/// rest length; `c_growth_per_step` is in MPa per load step, the unit of `c`
/// in eq. 19 being MPa per unit contraction).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// The model.
    pub params: Params,
    /// The effects the model has beyond the paper's (`pam_core::effects`);
    /// absent in a version-1 file.
    #[serde(default, skip_serializing_if = "no_effects")]
    pub effects: Effects,
    /// How it was fitted, when it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitSummary>,
}

impl ModelFile {
    /// A model file for `params`.
    pub fn new(params: Params, fit: Option<FitSummary>) -> ModelFile {
        ModelFile::with_effects(params, Effects::NONE, fit)
    }

    /// A model file for `params` with `effects` (version 2 when there are
    /// any, else version 1).
    pub fn with_effects(params: Params, effects: Effects, fit: Option<FitSummary>) -> ModelFile {
        ModelFile {
            format: FORMAT.to_string(),
            version: if no_effects(&effects) {
                VERSION
            } else {
                VERSION_EFFECTS
            },
            params,
            effects,
            fit,
        }
    }

    /// Pretty JSON text.
    pub fn to_json(&self) -> String {
        // Serialising plain data with finite floats cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default() + "\n"
    }
}

/// A model read from a file: the paper's coefficients and the effects it
/// carries beyond them.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedModel {
    /// The paper's model.
    pub coeffs: Coeffs,
    /// Its effects ([`Effects::NONE`] for a version-1 file or blob).
    pub effects: Effects,
}

/// Read a model: a JSON model file or a coefficient blob (told apart by the
/// blob's magic), validated by `Coeffs::new` and `Effects::validate`.
pub fn load(path: &Path) -> Result<LoadedModel> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let (params, effects) = if bytes.starts_with(&blob::BLOB_MAGIC) {
        blob::decode_model_params(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
    } else {
        let m: ModelFile = serde_json::from_slice(&bytes).map_err(|e| {
            anyhow::anyhow!(
                "{}:{}:{}: not a model file: {e}",
                path.display(),
                e.line(),
                e.column()
            )
        })?;
        if m.format != FORMAT || !(m.version == VERSION || m.version == VERSION_EFFECTS) {
            bail!(
                "{}: format `{}` version {} (expected `{FORMAT}` version {VERSION} or {VERSION_EFFECTS})",
                path.display(),
                m.format,
                m.version
            );
        }
        (m.params, m.effects)
    };
    let coeffs = Coeffs::new(params)
        .map_err(|e| anyhow::anyhow!("{}: invalid model: {e}", path.display()))?;
    effects
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: invalid effects: {e}", path.display()))?;
    Ok(LoadedModel { coeffs, effects })
}

/// A Rust source file defining `PARAMS: pam_core::Params` (for building the
/// coefficients into firmware or into pam-core's default).
pub fn rust_source(params: &Params, origin: &str) -> String {
    format!(
        "// Generated by pam-lab {version}: {origin}\n\
         // Do not edit: re-run the fit instead.\n\n\
         /// Model parameters identified by `pam-lab fit`.\n\
         pub const PARAMS: pam_core::Params = {};\n",
        params_literal(params, ParamsLayout::QUALIFIED),
        version = env!("CARGO_PKG_VERSION"),
    )
}

/// How [`params_literal`] writes a `pam_core::Params` expression.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamsLayout {
    /// Written before each of pam-core's type names: `"pam_core::"`, or
    /// `""` in a file that imports `Params`, `CriticalPoints` and `Point`.
    pub type_prefix: &'static str,
    /// Each `Point` on one line (`Point { contraction: …, pressure_mpa: … }`)
    /// rather than one field a line.
    pub inline_points: bool,
}

impl ParamsLayout {
    /// `model_params.rs`'s ([`rust_source`]): full paths, one field a line.
    pub const QUALIFIED: ParamsLayout = ParamsLayout {
        type_prefix: "pam_core::",
        inline_points: false,
    };
}

/// `params` as a Rust expression (from `Params {` to its closing brace, at
/// the indentation of an item), every value an [`f32_literal`] that reads
/// back to the same `f32`. The one writer of `Params` as source: pam-lab's
/// `model_params.rs` and bench-m4's `identified.rs` both use it.
pub fn params_literal(params: &Params, layout: ParamsLayout) -> String {
    let p = params;
    let f = f32_literal;
    let ty = layout.type_prefix;
    let point = |q: &pam_core::Point| {
        if layout.inline_points {
            format!(
                "{ty}Point {{ contraction: {}, pressure_mpa: {} }}",
                f(q.contraction),
                f(q.pressure_mpa)
            )
        } else {
            format!(
                "{ty}Point {{\n            contraction: {},\n            pressure_mpa: {},\n        }}",
                f(q.contraction),
                f(q.pressure_mpa)
            )
        }
    };
    format!(
        "{ty}Params {{\n    \
             min_load_n: {},\n    max_load_n: {},\n    load_step_n: {},\n    \
             points: {ty}CriticalPoints {{\n        \
                 root_contraction: {},\n        max_contraction: {},\n        max_pressure_mpa: {},\n        \
                 tangency: {},\n        \
                 inflection: {},\n    \
             }},\n    \
             root_regression_per_step: {},\n    max_regression_per_step: {},\n    \
             c_growth_per_step: {},\n    ellipse_height_mpa: {},\n}}",
        f(p.min_load_n),
        f(p.max_load_n),
        f(p.load_step_n),
        f(p.points.root_contraction),
        f(p.points.max_contraction),
        f(p.points.max_pressure_mpa),
        point(&p.points.tangency),
        point(&p.points.inflection),
        f(p.root_regression_per_step),
        f(p.max_regression_per_step),
        f(p.c_growth_per_step),
        f(p.ellipse_height_mpa),
    )
}

fn no_effects(e: &Effects) -> bool {
    *e == Effects::NONE
}

/// The coefficient blob of a model: version 1 for the paper's model, so
/// that firmware built before version 2 still reads it, version 2 with its
/// effects, version 3 with a shape's stroke table (`blob::encode_model`).
pub fn blob_bytes(params: &Params, effects: &Effects) -> Vec<u8> {
    let (bytes, len) = blob::encode_model(params, effects);
    bytes[..len].to_vec()
}

/// [`rust_source`] plus, for a model with effects, a constant
/// `EFFECTS: pam_core::Effects` (each effect `Some` with its parameters,
/// or `None`).
pub fn rust_source_with_effects(params: &Params, effects: &Effects, origin: &str) -> String {
    let mut src = rust_source(params, origin);
    if no_effects(effects) {
        return src;
    }
    let f = f32_literal;
    let opt = |v: Option<String>| v.map_or("None".to_string(), |s| format!("Some({s})"));
    let memory = opt(effects.memory.map(|m| {
        format!(
            "pam_core::effects::NonLocalMemory {{\n        shape: {},\n        merge_span: {},\n    }}",
            f(m.shape),
            f(m.merge_span)
        )
    }));
    let rate = opt(effects.rate.map(|r| {
        format!(
            "pam_core::effects::RateDependence {{\n        scale_at_rest: {},\n        scale_per_mpa_per_s: {},\n        exponent: {},\n        filter_time_s: {},\n        max_rate_mpa_per_s: {},\n    }}",
            f(r.scale_at_rest),
            f(r.scale_per_mpa_per_s),
            f(r.exponent),
            f(r.filter_time_s),
            f(r.max_rate_mpa_per_s)
        )
    }));
    let creep = opt(effects.creep.map(|c| {
        format!(
            "pam_core::effects::Creep {{\n        gain: {},\n        time_constant_s: {},\n    }}",
            f(c.gain),
            f(c.time_constant_s)
        )
    }));
    let width = opt(effects.width.map(|w| {
        format!(
            "pam_core::effects::LoadDependentWidth {{\n        scale_at_min_load: {},\n        scale_per_step: {},\n    }}",
            f(w.scale_at_min_load),
            f(w.scale_per_step)
        )
    }));
    let shape = opt(effects.shape.as_ref().map(constraint_shape_literal));
    let pressure_lag = opt(effects.pressure_lag.map(|l| {
        format!(
            "pam_core::effects::PressureLag {{\n        time_constant_s: {},\n    }}",
            f(l.time_constant_s)
        )
    }));
    let pressure_delay = opt(effects.pressure_delay.map(|d| {
        format!(
            "pam_core::effects::PressureDelay {{\n        delay_s: {},\n    }}",
            f(d.delay_s)
        )
    }));
    src.push_str(&format!(
        "\n/// The effects of the model beyond the paper's, identified with it.\n\
         pub const EFFECTS: pam_core::Effects = pam_core::Effects {{\n    \
         memory: {memory},\n    rate: {rate},\n    creep: {creep},\n    width: {width},\n    shape: {shape},\n    pressure_lag: {pressure_lag},\n    pressure_delay: {pressure_delay},\n}};\n"
    ));
    src
}

/// A constraint shape as a Rust expression (`pam_core::effects::ConstraintShape { .. }`,
/// its stroke table's knots written out unless it is the identity): what
/// `model_params.rs` and bench-m4's `identified.rs` carry.
pub fn constraint_shape_literal(c: &ConstraintShape) -> String {
    let f = f32_literal;
    format!(
        "pam_core::effects::ConstraintShape {{\n        bulge: {},\n        tilt: {},\n        bulge_per_step: {},\n        tilt_per_step: {},\n        root_shift: {},\n        end_shift: {},\n        root_shift_per_step: {},\n        end_shift_per_step: {},\n        root_shift_per_step_sq: {},\n        end_shift_per_step_sq: {},\n        table: {},\n    }}",
        f(c.bulge),
        f(c.tilt),
        f(c.bulge_per_step),
        f(c.tilt_per_step),
        f(c.root_shift),
        f(c.end_shift),
        f(c.root_shift_per_step),
        f(c.end_shift_per_step),
        f(c.root_shift_per_step_sq),
        f(c.end_shift_per_step_sq),
        if c.table.is_neutral() {
            "pam_core::effects::StrokeTable::NEUTRAL".to_string()
        } else {
            let nodes: Vec<String> = c
                .table
                .knots
                .iter()
                .map(|k| format!("[{}]", k.map(f).join(", ")))
                .collect();
            format!(
                "pam_core::effects::StrokeTable {{\n            knots: [\n                {},\n            ],\n        }}",
                nodes.join(",\n                ")
            )
        }
    )
}

/// An `f32` as a Rust literal: `{:?}` (the shortest text that reads back
/// to the same value) with a decimal point (`100.0`, not `100`). A value
/// that is not finite is left as `{:?}` prints it (`inf`, `NaN`: no
/// literal, so generated source holding one does not compile). The one
/// formatter of generated source: pam-lab's `model_params.rs` and
/// bench-m4's `identified.rs`.
pub fn f32_literal(v: f32) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') || !v.is_finite() {
        s
    } else {
        format!("{s}.0")
    }
}

/// A model's three files, `(file name, bytes)`: `model.json`
/// ([`ModelFile`]), `model.blob` ([`blob_bytes`]) and `model_params.rs`
/// ([`rust_source_with_effects`]), for a caller to write as one output set.
/// Refuses a model that does not validate (`Coeffs::new`,
/// `Effects::validate`), and checks that the blob decodes to the same model
/// and the JSON reads back to the same parameters.
pub fn model_files(
    params: &Params,
    effects: &Effects,
    fit: Option<FitSummary>,
    origin: &str,
) -> Result<Vec<(&'static str, Vec<u8>)>> {
    Coeffs::new(*params).map_err(|e| anyhow::anyhow!("invalid model: {e}"))?;
    effects
        .validate()
        .map_err(|e| anyhow::anyhow!("invalid effects: {e}"))?;
    let json = ModelFile::with_effects(*params, *effects, fit).to_json();
    let blob = blob_bytes(params, effects);
    let (c, e) = blob::decode_model(&blob)
        .map_err(|e| anyhow::anyhow!("the blob does not read back: {e}"))?;
    let read: ModelFile = serde_json::from_str(&json)
        .map_err(|e| anyhow::anyhow!("model.json does not read back: {e}"))?;
    if c.params() != params || e != *effects || read.params != *params {
        anyhow::bail!("the model files do not read back to the model");
    }
    Ok(vec![
        ("model.json", json.into_bytes()),
        ("model.blob", blob),
        (
            "model_params.rs",
            rust_source_with_effects(params, effects, origin).into_bytes(),
        ),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_and_blob_round_trip_through_load() {
        let dir = tempfile::tempdir().unwrap();
        let json = dir.path().join("m.json");
        std::fs::write(&json, ModelFile::new(Params::DEFAULT, None).to_json()).unwrap();
        assert_eq!(load(&json).unwrap().coeffs.params(), &Params::DEFAULT);
        let text = std::fs::read_to_string(&json).unwrap();
        assert!(text.contains("\"max_pressure_mpa\": 0.50096667,"), "{text}");
        let b = dir.path().join("m.blob");
        std::fs::write(&b, blob::encode(&Params::DEFAULT)).unwrap();
        assert_eq!(load(&b).unwrap().coeffs.params(), &Params::DEFAULT);
    }

    #[test]
    fn corrupt_files_are_refused_with_their_name() {
        let dir = tempfile::tempdir().unwrap();
        let b = dir.path().join("bad.blob");
        let mut bytes = blob::encode(&Params::DEFAULT);
        bytes[20] ^= 1;
        std::fs::write(&b, bytes).unwrap();
        let e = load(&b).unwrap_err().to_string();
        assert!(e.contains("bad.blob") && e.contains("CRC"), "{e}");
        let j = dir.path().join("bad.json");
        std::fs::write(&j, "{\"format\": 3}").unwrap();
        assert!(load(&j).unwrap_err().to_string().contains("bad.json:1:"));
    }

    #[test]
    fn rust_source_reads_back_exactly() {
        let src = rust_source(&Params::DEFAULT, "test");
        assert!(src.contains("root_contraction: 0.015122114,"), "{src}");
        assert!(src.contains("max_pressure_mpa: 0.50096667,"), "{src}");
        assert!(src.contains("min_load_n: 100.0,"), "{src}");
        assert!(
            src.contains(
                "        tangency: pam_core::Point {\n            contraction: 0.068183854,\n"
            ),
            "{src}"
        );
    }

    #[test]
    fn f32_literals_and_the_inline_layout() {
        assert_eq!(f32_literal(100.0), "100.0");
        assert_eq!(f32_literal(-0.0), "-0.0");
        assert_eq!(f32_literal(1e-7), "1e-7");
        assert_eq!(f32_literal(f32::INFINITY), "inf");
        let inline = ParamsLayout {
            type_prefix: "",
            inline_points: true,
        };
        let src = params_literal(&Params::DEFAULT, inline);
        assert!(
            src.starts_with("Params {\n    min_load_n: 100.0,\n"),
            "{src}"
        );
        assert!(
            src.contains("    points: CriticalPoints {\n")
                && src
                    .contains("        tangency: Point { contraction: 0.068183854, pressure_mpa: "),
            "{src}"
        );
        assert!(src.ends_with("\n}") && !src.contains("pam_core::"), "{src}");
    }

    /// Write [`model_files`]' output into `dir`, as a command's output set does.
    fn write_model_files(
        dir: &Path,
        params: &Params,
        effects: &Effects,
        fit: Option<FitSummary>,
        origin: &str,
    ) -> Result<Vec<std::path::PathBuf>> {
        let files = model_files(params, effects, fit, origin)?;
        Ok(files
            .into_iter()
            .map(|(name, bytes)| {
                let p = dir.join(name);
                std::fs::write(&p, bytes).unwrap();
                p
            })
            .collect())
    }

    fn memory_model() -> Effects {
        Effects {
            memory: Some(pam_core::effects::NonLocalMemory {
                shape: 1.5,
                merge_span: 0.11,
            }),
            ..Effects::NONE
        }
    }

    #[test]
    fn a_model_with_effects_writes_v2_json_blob_and_constants() {
        let dir = tempfile::tempdir().unwrap();
        let e = memory_model();
        let written = write_model_files(dir.path(), &Params::DEFAULT, &e, None, "test").unwrap();
        assert_eq!(written.len(), 3);
        // JSON: version 2 with the effects, read back by serde and by `load`.
        let text = std::fs::read_to_string(dir.path().join("model.json")).unwrap();
        let m: ModelFile = serde_json::from_str(&text).unwrap();
        assert_eq!(
            (m.version, m.effects, m.params),
            (VERSION_EFFECTS, e, Params::DEFAULT)
        );
        assert_eq!(
            load(&dir.path().join("model.json"))
                .unwrap()
                .coeffs
                .params(),
            &Params::DEFAULT
        );
        // Blob: version 2 with the memory, as the firmware decodes it.
        let bytes = std::fs::read(dir.path().join("model.blob")).unwrap();
        assert_eq!(bytes.len(), blob::BLOB_V2_LEN);
        let (c, back) = blob::decode_model(&bytes).unwrap();
        assert_eq!((c.params(), back), (&Params::DEFAULT, e));
        let loaded = load(&dir.path().join("model.blob")).unwrap();
        assert_eq!(
            (loaded.coeffs.params(), loaded.effects),
            (&Params::DEFAULT, e)
        );
        // Constants.
        let src = std::fs::read_to_string(dir.path().join("model_params.rs")).unwrap();
        assert!(
            src.contains("pub const EFFECTS: pam_core::Effects"),
            "{src}"
        );
        assert!(
            src.contains("shape: 1.5,") && src.contains("merge_span: 0.11,"),
            "{src}"
        );
        assert!(src.contains("rate: None,"), "{src}");
    }

    #[test]
    fn the_paper_model_still_writes_version_1() {
        let dir = tempfile::tempdir().unwrap();
        write_model_files(dir.path(), &Params::DEFAULT, &Effects::NONE, None, "test").unwrap();
        let bytes = std::fs::read(dir.path().join("model.blob")).unwrap();
        assert_eq!(bytes, blob::encode(&Params::DEFAULT).to_vec());
        let text = std::fs::read_to_string(dir.path().join("model.json")).unwrap();
        assert!(
            text.contains("\"version\": 1,") && !text.contains("effects"),
            "{text}"
        );
        let src = std::fs::read_to_string(dir.path().join("model_params.rs")).unwrap();
        assert!(!src.contains("EFFECTS"), "{src}");
    }

    #[test]
    fn invalid_effects_are_refused_and_nothing_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let bad = Effects {
            memory: Some(pam_core::effects::NonLocalMemory {
                shape: f32::NAN,
                merge_span: 1.0,
            }),
            ..Effects::NONE
        };
        assert!(write_model_files(dir.path(), &Params::DEFAULT, &bad, None, "t").is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
