//! The build script of the apps beside this board example (`../stm32f405-rtic`,
//! `../stm32f405-embassy`, each `build = "../stm32f405/apps_build.rs"`): the link scripts
//! with this board's `memory.x`, the bare-metal target only. The apps hold their table as a
//! `static` in source, so unlike `build.rs` this generates nothing.

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=../stm32f405/apps_build.rs");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    // cortex-m-rt's link.x does `INCLUDE memory.x`: the board's map, put on the link path.
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let map = manifest.join("../stm32f405/memory.x");
    println!("cargo:rerun-if-changed={}", map.display());
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy(&map, out.join("memory.x")).expect("copy the board's memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
