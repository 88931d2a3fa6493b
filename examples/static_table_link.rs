//! The recommended link, sized: a `ThreeAxisSensorPerAxis` holding a `&'static Table` built
//! by `const fn`s (no postcard decode), split into its two halves, every reading through
//! `on_scratchpad` or `on_missed_reading`, every IMU cycle through the applier. Its flash
//! minus `size_baseline`'s is `core_flash_bytes_static_table` (`cargo xtask bench-target`).
//! Like `panic_check`, its panic handler calls a function defined nowhere, so the link also
//! proves that no panic is reachable from this configuration's paths.
#![cfg_attr(target_os = "none", no_std, no_main)]

mod common;

#[cfg(target_os = "none")]
mod target {
    use core::hint::black_box;

    use cortex_m_rt::entry;

    use crate::common::rt;
    use crate::common::sized_statics::{self, TABLE};
    use qfa_thermal::{Config, Table, ThreeAxisSensorPerAxis};

    #[entry]
    fn main() -> ! {
        sized_statics::keep();
        let Ok(mut c) = ThreeAxisSensorPerAxis::new(black_box(Config::default())) else { rt::exit(3) };
        let table: &'static Table = black_box(&TABLE);
        let _ = black_box(c.set_table(table));
        let (mut up, mut ap) = c.split();
        loop {
            let sp: [u8; 9] = black_box([0; 9]);
            let _ = black_box(up.on_scratchpad(black_box(0), black_box(0), &sp));
            let _ = black_box(up.on_missed_reading(black_box(1), black_box(0)));
            black_box(ap.cycle(black_box([0; 3]), black_box(0)));
            if black_box(true) {
                break;
            }
        }
        rt::exit(0)
    }

    crate::common::panic_free_handlers!();
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("static_table_link is a link-time size check for thumbv7em-none-eabihf: run `cargo xtask bench-target`");
    std::process::exit(2);
}
