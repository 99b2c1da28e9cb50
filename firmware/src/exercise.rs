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
    triangle_over(t_s, PERIOD_S, LOW, HIGH)
}

/// A triangle `low → high → low` with period `period_s` at time `t_s`
/// (≥ 0): [`triangle`]'s shape over any span and pace (`pam-lab
/// diagnose`'s closed-loop check runs it over a model's stroke).
pub fn triangle_over(t_s: f32, period_s: f32, low: f32, high: f32) -> f32 {
    let phase = t_s / period_s;
    let frac = phase - (phase as u32) as f32;
    let up = if frac < 0.5 {
        2.0 * frac
    } else {
        2.0 - 2.0 * frac
    };
    low + (high - low) * up
}
