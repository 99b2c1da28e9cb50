//! Baseline hysteresis models for the on-target benchmarks, beside pam-core.
#![cfg_attr(not(test), no_std)]
