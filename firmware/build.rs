//! Link settings for the bare-metal target only, so host builds of this crate stay plain.

use std::env;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../memory.x");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    // cortex-m-rt's link.x does `INCLUDE memory.x`. The linker looks in its working
    // directory first, which cargo sets to the workspace root: the repository's `memory.x`
    // (QEMU mps2-an386), shared with the root crate's examples. No link-search path is
    // added, so no other workspace can pick this map up.
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
}
