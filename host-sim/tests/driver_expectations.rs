//! Expectation tests of the firmware's valve drivers with embedded-hal-mock:
//! the exact PWM transactions a flow command produces.

use embedded_hal_mock::eh1::pwm::{Mock, Transaction as T};
use firmware::hal::{ProportionalValve, SafeState, Valve, ValvePair, ValvePairConfig};

#[test]
fn valve_pair_closes_before_it_opens() {
    // Fill at half rate: the exhaust is written closed first, then the inlet
    // at 0.05 + 0.95·0.5 = 52.5 % of 1000. Then the safe state: the inlet
    // closed first, then the exhaust fully open.
    let inlet = Mock::new(&[
        T::max_duty_cycle(1000),
        T::set_duty_cycle(525),
        T::max_duty_cycle(1000),
        T::set_duty_cycle(0),
    ]);
    let exhaust = Mock::new(&[
        T::max_duty_cycle(1000),
        T::set_duty_cycle(0),
        T::max_duty_cycle(1000),
        T::set_duty_cycle(1000),
    ]);
    let mut pair = ValvePair::new(inlet, exhaust, ValvePairConfig::DEFAULT).unwrap();
    pair.set_flow(0.5).unwrap();
    pair.set_safe(SafeState::Exhaust).unwrap();
    let (mut i, mut e) = pair.release();
    i.done();
    e.done();
}

#[test]
fn proportional_valve_duty_for_commands() {
    let pwm = Mock::new(&[
        T::max_duty_cycle(1000),
        T::set_duty_cycle(500),
        T::max_duty_cycle(1000),
        T::set_duty_cycle(875),
        T::max_duty_cycle(1000),
        T::set_duty_cycle(125),
        T::set_duty_cycle(0),
    ]);
    let mut v = ProportionalValve::new(pwm, 0.5).unwrap();
    v.set_flow(0.0).unwrap();
    v.set_flow(0.75).unwrap();
    v.set_flow(-0.75).unwrap();
    v.set_safe(SafeState::Exhaust).unwrap();
    v.release().done();
}
