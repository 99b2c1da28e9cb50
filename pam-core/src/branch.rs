//! Which branch of the hysteresis loop the muscle is on.

/// Branch of the hysteresis loop.
///
/// On the contraction branch the pressure rises and the muscle shortens
/// (eq. 25, `HMC = CM + y_hys`); on the expansion branch the pressure falls
/// and the muscle lengthens (eq. 26, `HME = CM − y_hys`). For the same
/// contraction the contraction branch needs the higher pressure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Branch {
    /// Pressure rising, muscle contracting: eq. (25).
    Contraction,
    /// Pressure falling, muscle expanding: eq. (26).
    Expansion,
}

impl Branch {
    /// Sign of the ellipse offset on this branch: `+1` on eq. (25), `−1` on eq. (26).
    pub const fn offset_sign(self) -> f32 {
        match self {
            Branch::Contraction => 1.0,
            Branch::Expansion => -1.0,
        }
    }

    /// The other branch.
    pub const fn opposite(self) -> Branch {
        match self {
            Branch::Contraction => Branch::Expansion,
            Branch::Expansion => Branch::Contraction,
        }
    }
}
