//! The exercise trajectory of the images: the desired contraction, a
//! triangle `LOW → HIGH → LOW` with period [`PERIOD_S`]. The board
//! controller follows it (replace it with the orthosis's own set-point
//! source), and the self-test scenario tracks it on the simulated muscle.

/// Lower end of the triangle, contraction.
pub const LOW: f32 = 0.06;
/// Upper end of the triangle, contraction.
pub const HIGH: f32 = 0.16;
/// Period of the triangle, s.
pub const PERIOD_S: f32 = 4.0;

/// The desired contraction at time `t_s` (≥ 0).
pub fn triangle(t_s: f32) -> f32 {
    let phase = t_s / PERIOD_S;
    let frac = phase - (phase as u32) as f32;
    let up = if frac < 0.5 {
        2.0 * frac
    } else {
        2.0 - 2.0 * frac
    };
    LOW + (HIGH - LOW) * up
}
