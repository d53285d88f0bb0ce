//! Puts `device.x` (the interrupt handlers' default bindings, included by cortex-m-rt's `link.x`)
//! on the linker search path, as an svd2rust device crate does.
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_default());
    if let Err(e) = std::fs::copy("device.x", out.join("device.x")) {
        panic!("rths-board-mps2-an500 build script: cannot copy device.x: {e}");
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=device.x");
    println!("cargo:rerun-if-changed=build.rs");
}
