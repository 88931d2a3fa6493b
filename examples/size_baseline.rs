//! The size programs' runtime and statics without the core: vector table, reset, semihosting
//! exit, a table's bytes and a table in flash. `panic_check`'s flash minus this is
//! `core_flash_bytes`, `static_table_link`'s minus this `core_flash_bytes_static_table`
//! (`cargo xtask bench-target`).
#![cfg_attr(target_os = "none", no_std, no_main)]

mod common;

#[cfg(target_os = "none")]
mod target {
    use core::hint::black_box;

    use cortex_m_rt::entry;

    use crate::common::{rt, sized_statics};

    #[entry]
    fn main() -> ! {
        sized_statics::keep();
        rt::exit(black_box(0))
    }

    crate::common::panic_free_handlers!();
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("size_baseline is a target program: run `cargo xtask bench-target`");
    std::process::exit(2);
}
