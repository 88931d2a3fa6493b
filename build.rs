//! Link settings for this crate's examples on the bare-metal target (`examples/`, run under
//! QEMU by `cargo xtask demo-qemu`). Nothing for the library: a crate that depends on
//! qfa-thermal links with its own memory map and its own linker scripts.

use std::env;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    // cortex-m-rt's link.x does `INCLUDE memory.x`, found in the linker's working directory,
    // the workspace root: the repository's `memory.x`. Deliberately no
    // `cargo:rustc-link-search`: a library's search paths reach every crate that links it,
    // and this map would then be found before a board's own.
    println!("cargo:rustc-link-arg-examples=--nmagic");
    println!("cargo:rustc-link-arg-examples=-Tlink.x");
}
