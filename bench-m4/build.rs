//! Puts the workspace's `memory.x` on the linker path for the chip build.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap());
    let memory_x = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap()).join("../memory.x");
    if env::var("TARGET").is_ok_and(|t| t.starts_with("thumb")) {
        fs::copy(&memory_x, out.join("memory.x")).expect("memory.x at the workspace root");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
