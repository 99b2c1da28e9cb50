//! Boot: a blob decoded once into the controller that runs its model: the
//! paper model's coefficient blob (`PAMC`, versions 1–4) or a Preisach
//! blob (`PAMP`, [`pam_core::preisach::blob`]), told apart by the magic.

use crate::controller::preisach::{PREISACH_LOADS, PREISACH_ROWS};
use crate::controller::{
    ConfigError, Controller, ControllerConfig, Feedforward, ModelLimits, Setting,
};
use pam_core::preisach::blob::PREISACH_BLOB_MAGIC;
use pam_core::{Coeffs, Effects};

/// A controller booted from a blob, and what boot learnt on the way.
#[derive(Clone, Debug)]
pub struct Booted {
    /// The controller, with the feedforward that runs the blob's model.
    pub controller: Controller,
    /// The validated effects the blob carries ([`Effects::NONE`] for version 1
    /// and for a Preisach blob).
    pub effects: Effects,
    /// The load the tracker started at, N (before the tracker's clamp to
    /// the calibrated range).
    pub initial_load_n: f32,
}

/// Why [`boot`] refused: the blob itself, or the controller built from it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BootError {
    /// The blob failed magic, version, length, CRC-32, or the validation of
    /// its parameters or effects.
    Blob(ConfigError),
    /// The blob was good, but the controller refused its configuration or
    /// the model ([`Controller::new`]).
    Controller(ConfigError),
}

impl BootError {
    /// The controller's reason, whichever step refused.
    pub fn reason(&self) -> &ConfigError {
        match self {
            BootError::Blob(e) | BootError::Controller(e) => e,
        }
    }
}

impl From<BootError> for ConfigError {
    fn from(e: BootError) -> Self {
        *e.reason()
    }
}

impl core::fmt::Display for BootError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Display::fmt(self.reason(), f)
    }
}

impl core::error::Error for BootError {}

/// Decode `blob` once and build the controller that runs its model: the
/// one path from blob bytes to a [`Controller`] (the board controller, the
/// self-test image, [`Controller::from_blob`] and host-sim's boot checks).
/// The blob must pass magic, version, length and CRC-32, then the
/// validation of its effects and parameters (a Preisach blob: pam-core's
/// [`decode`](pam_core::preisach::blob::decode) of a 16-row table at 6
/// loads, which validates the table); no allocation, no panic.
///
/// `config.feedforward` is replaced by the one the blob's model asks for
/// (the rules of [`model_from_blob`]; a Preisach blob turns every model
/// feedforward into [`Feedforward::Preisach`], keeps [`Feedforward::Off`]
/// and refuses [`Feedforward::Constraint`], which it has no model for);
/// `initial_load_n` is called once, after the blob passed, with the
/// model's calibrated range (a board reads its load cell here and falls
/// back to the lightest calibrated load on a failed read).
///
/// ```
/// use firmware::boot::{boot, BootError};
/// use firmware::controller::{ControllerConfig, Feedforward};
/// use pam_core::effects::{Creep, Effects};
///
/// let effects = Effects {
///     creep: Some(Creep { gain: 0.3, time_constant_s: 2.0 }),
///     ..Effects::NONE
/// };
/// let blob = pam_core::blob::encode_v2(&pam_core::Params::DEFAULT, &effects);
/// // The tracker starts at the lightest calibrated load.
/// let booted = boot(&blob, ControllerConfig::DEFAULT, |limits| limits.min_load_n).unwrap();
/// assert_eq!(booted.effects, effects);
/// assert_eq!(booted.controller.config().feedforward, Feedforward::HysteresisEffects(effects));
/// // One flipped bit: the blob is refused before any controller is built.
/// let mut bad = blob;
/// bad[20] ^= 0x10;
/// assert!(matches!(boot(&bad, ControllerConfig::DEFAULT, |_| 200.0), Err(BootError::Blob(_))));
/// ```
pub fn boot(
    blob: &[u8],
    config: ControllerConfig,
    initial_load_n: impl FnOnce(&ModelLimits) -> f32,
) -> Result<Booted, BootError> {
    if blob.get(..4) == Some(&PREISACH_BLOB_MAGIC[..]) {
        return boot_preisach(blob, config, initial_load_n);
    }
    let (coeffs, effects) = decode(blob).map_err(BootError::Blob)?;
    let feedforward = feedforward_for(&effects, config.feedforward);
    let load_n = initial_load_n(&ModelLimits::of_coeffs(&coeffs));
    let controller = Controller::new(
        coeffs,
        ControllerConfig {
            feedforward,
            ..config
        },
        load_n,
    )
    .map_err(BootError::Controller)?;
    Ok(Booted {
        controller,
        effects,
        initial_load_n: load_n,
    })
}

/// [`boot`] for a Preisach blob: pam-core's decoder (framing, the reader's
/// size, CRC-32, the table's validation), then the controller that runs
/// [`Feedforward::Preisach`] (or the PI alone, [`Feedforward::Off`]).
fn boot_preisach(
    blob: &[u8],
    config: ControllerConfig,
    initial_load_n: impl FnOnce(&ModelLimits) -> f32,
) -> Result<Booted, BootError> {
    let table = pam_core::preisach::blob::decode::<PREISACH_ROWS, PREISACH_LOADS>(blob)
        .map_err(|e| BootError::Blob(ConfigError::Coefficients(e)))?;
    let feedforward = match config.feedforward {
        Feedforward::Off => Feedforward::Off,
        // The comparison mode of the paper's constraint model alone: a
        // Preisach model has none.
        Feedforward::Constraint => {
            return Err(BootError::Controller(ConfigError::Invalid(
                Setting::FeedforwardModel,
            )))
        }
        _ => Feedforward::Preisach,
    };
    let load_n = initial_load_n(&crate::controller::preisach::model_limits(&table));
    let controller = Controller::new_preisach(
        table,
        ControllerConfig {
            feedforward,
            ..config
        },
        load_n,
    )
    .map_err(BootError::Controller)?;
    Ok(Booted {
        controller,
        effects: Effects::NONE,
        initial_load_n: load_n,
    })
}

/// The blob's coefficients and effects: framing and CRC, then the effects
/// and the parameters validated, in that order.
pub(crate) fn decode(blob: &[u8]) -> Result<(Coeffs, Effects), ConfigError> {
    let (params, effects) =
        pam_core::blob::decode_model_params(blob).map_err(ConfigError::Coefficients)?;
    effects.validate().map_err(ConfigError::Coefficients)?;
    let coeffs = Coeffs::new(params).map_err(ConfigError::Coefficients)?;
    Ok((coeffs, effects))
}

/// The feedforward that runs a model with `effects`, from the configured
/// one (the rules of [`model_from_blob`]).
pub(crate) fn feedforward_for(effects: &Effects, configured: Feedforward) -> Feedforward {
    let memory_only = Effects {
        memory: effects.memory,
        ..Effects::NONE
    } == *effects;
    match (effects.memory, configured) {
        (_, ff) if *effects == Effects::NONE => ff,
        (
            Some(m),
            Feedforward::Hysteresis
            | Feedforward::HysteresisMemory(_)
            | Feedforward::HysteresisEffects(_),
        ) if memory_only => Feedforward::HysteresisMemory(m),
        (
            _,
            Feedforward::Hysteresis
            | Feedforward::HysteresisMemory(_)
            | Feedforward::HysteresisEffects(_),
        ) => Feedforward::HysteresisEffects(*effects),
        (_, ff) => ff,
    }
}

/// The coefficients of a blob (version 1 or 2, [`pam_core::blob`]) and the
/// feedforward that runs its model, from the configured one:
///
/// * a model with effects turns [`Feedforward::Hysteresis`] (and a
///   hand-set [`Feedforward::HysteresisMemory`] or
///   [`Feedforward::HysteresisEffects`]) into the feedforward that inverts
///   the blob's model with all of them: `HysteresisMemory` with the blob's
///   memory shape and merge span when the memory is its only effect,
///   `HysteresisEffects` with the blob's effects otherwise (pam-core's
///   [`ModelInverse`](pam_core::feedforward::ModelInverse) either way);
/// * a model without effects keeps the configured feedforward (a hand-set
///   memory or effects feedforward included);
/// * the comparison modes [`Feedforward::Constraint`] and
///   [`Feedforward::Off`] stay as configured.
///
/// The effects are validated here (what `decode_model` checks). The same
/// decoding and rules as [`boot`], without building the controller.
///
/// ```
/// use firmware::boot::model_from_blob;
/// use firmware::controller::Feedforward;
/// use pam_core::effects::{Creep, Effects};
///
/// let effects = Effects {
///     creep: Some(Creep { gain: 0.3, time_constant_s: 2.0 }),
///     ..Effects::NONE
/// };
/// let blob = pam_core::blob::encode_v2(&pam_core::Params::DEFAULT, &effects);
/// let (_, ff) = model_from_blob(&blob, Feedforward::Hysteresis).unwrap();
/// assert_eq!(ff, Feedforward::HysteresisEffects(effects));
/// // The paper's model alone from a version-1 blob.
/// let plain = pam_core::blob::encode(&pam_core::Params::DEFAULT);
/// let (_, ff) = model_from_blob(&plain, Feedforward::Hysteresis).unwrap();
/// assert_eq!(ff, Feedforward::Hysteresis);
/// ```
pub fn model_from_blob(
    blob: &[u8],
    feedforward: Feedforward,
) -> Result<(Coeffs, Feedforward), ConfigError> {
    let (coeffs, effects) = decode(blob)?;
    Ok((coeffs, feedforward_for(&effects, feedforward)))
}

impl Controller {
    /// A controller from a coefficient blob in pam-core's format
    /// ([`pam_core::blob`]: magic, version, length, CRC-32, then the
    /// parameters and effects are validated), with the feedforward the
    /// blob's model asks for ([`model_from_blob`]). A blob that fails any
    /// check, or whose model this controller cannot run, is refused.
    /// [`boot`] with a fixed initial load.
    pub fn from_blob(
        blob: &[u8],
        config: ControllerConfig,
        initial_load_n: f32,
    ) -> Result<Controller, ConfigError> {
        boot(blob, config, |_| initial_load_n)
            .map(|b| b.controller)
            .map_err(ConfigError::from)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::Params;

    #[test]
    fn one_decode_gives_what_model_from_blob_and_from_blob_give() {
        let memory = pam_core::effects::NonLocalMemory {
            shape: 1.0,
            merge_span: 0.1,
        };
        let with_memory = Effects {
            memory: Some(memory),
            ..Effects::NONE
        };
        for blob in [
            pam_core::blob::encode(&Params::DEFAULT).to_vec(),
            pam_core::blob::encode_v2(&Params::DEFAULT, &with_memory).to_vec(),
        ] {
            let b = boot(&blob, ControllerConfig::DEFAULT, |_| 200.0).unwrap();
            let (coeffs, ff) = model_from_blob(&blob, Feedforward::Hysteresis).unwrap();
            assert_eq!(b.controller.coeffs().unwrap().params(), coeffs.params());
            assert_eq!(b.controller.config().feedforward, ff);
            assert_eq!(b.initial_load_n, 200.0);
            let c = Controller::from_blob(&blob, ControllerConfig::DEFAULT, 200.0).unwrap();
            assert_eq!(c.config(), b.controller.config());
        }
        let b = boot(
            &pam_core::blob::encode_v2(&Params::DEFAULT, &with_memory),
            ControllerConfig::DEFAULT,
            |_| 200.0,
        )
        .unwrap();
        assert_eq!(b.effects, with_memory);
    }

    #[test]
    fn the_load_is_asked_for_only_after_the_blob_passed() {
        let mut bad = pam_core::blob::encode(&Params::DEFAULT);
        bad[20] ^= 0x10;
        let mut asked = false;
        let e = boot(&bad, ControllerConfig::DEFAULT, |_| {
            asked = true;
            200.0
        })
        .unwrap_err();
        assert!(!asked);
        assert_eq!(
            e,
            BootError::Blob(ConfigError::Coefficients(pam_core::Error::Blob(
                "CRC mismatch"
            )))
        );
        // The lightest calibrated load, from the decoded coefficients.
        let good = pam_core::blob::encode(&Params::DEFAULT);
        let b = boot(&good, ControllerConfig::DEFAULT, |l| l.min_load_n).unwrap();
        assert_eq!(b.initial_load_n, Params::DEFAULT.min_load_n);
    }

    #[test]
    fn a_configuration_the_controller_refuses_is_not_a_blob_error() {
        let blob = pam_core::blob::encode(&Params::DEFAULT);
        let config = ControllerConfig {
            dt_s: -1.0,
            ..ControllerConfig::DEFAULT
        };
        let e = boot(&blob, config, |_| 200.0).unwrap_err();
        assert!(matches!(e, BootError::Controller(_)), "{e:?}");
        assert_eq!(
            ConfigError::from(e),
            Controller::from_blob(&blob, config, 200.0).unwrap_err()
        );
    }
}
