//! Build script of the core crate: for the firmware binary only (feature `firmware` on the
//! ARM target) it puts the top-level `memory.x` on the link search path and passes the
//! cortex-m-rt and defmt linker scripts. Host builds, and other crates that build the core
//! for ARM with their own memory map (bench-m4), get nothing from here.

use std::env;
use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    let target = env::var("TARGET").unwrap_or_default();
    let firmware = env::var_os("CARGO_FEATURE_FIRMWARE").is_some();
    if !(firmware && target.starts_with("thumbv")) {
        return;
    }
    let root = PathBuf::from(env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    println!("cargo:rustc-link-search={}", root.display());
    // Scoped to the firmware binary: link.x (cortex-m-rt, which includes memory.x) and
    // defmt.x; --nmagic stops the linker padding sections to page boundaries.
    for arg in ["--nmagic", "-Tlink.x", "-Tdefmt.x"] {
        println!("cargo:rustc-link-arg-bin=dollop-firmware={arg}");
    }
}
