//! Work in progress: see the open issues.
#![no_std]
