//! The exact step of a first-order lag, shared by the effects that lag
//! (creep and the pressure lag).

/// The gain of a first-order lag `τ·ẏ = u − y` over one step of `dt_s`:
/// `1 − e^(−dt/τ)`, the exact zero-order-hold step; 0 (the lag held) for a
/// `dt_s` outside `(0, 10]` s. Creep's and the pressure lag's.
pub fn first_order_gain(dt_s: f32, time_constant_s: f32) -> f32 {
    if dt_s > 0.0 && dt_s <= 10.0 {
        1.0 - libm::expf(-dt_s / time_constant_s)
    } else {
        0.0
    }
}
