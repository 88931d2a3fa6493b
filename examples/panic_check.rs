//! Link-time proof that no panic is reachable from the core's table loader, slow path and
//! fast path: the panic handler calls a function that is defined nowhere, so the link fails
//! if any panic survives optimization. Every input (config, table bytes, readings, pulse
//! counts, timestamps) comes through `black_box`, so the proof covers all of them.
//! Run: `cargo xtask panic-check` (release, LTO).
#![cfg_attr(target_os = "none", no_std, no_main)]

mod common;

#[cfg(target_os = "none")]
mod target {
    use core::hint::black_box;

    use cortex_m_rt::entry;

    use crate::common::rt;
    use crate::common::sized_statics::{self, TABLE_BYTES};
    use qfa_thermal::{Compensator, Config};

    #[entry]
    fn main() -> ! {
        sized_statics::keep();
        // A refused config is an error value, not a panic: park on it.
        let Ok(mut c) = Compensator::<3, 32>::new(black_box(Config::default())) else { rt::exit(3) };
        let table: &[u8] = black_box(&TABLE_BYTES[..]);
        let _ = black_box(c.load_table(table));
        loop {
            let sp: [u8; 9] = black_box([0; 9]);
            let _ = black_box(c.on_scratchpad(0, black_box(0), &sp));
            let _ = black_box(c.on_raw(0, black_box(0), black_box(0)));
            black_box(c.cycle(black_box([0; 3]), black_box(0)));
            black_box(c.cycle_counters(black_box([0; 3]), black_box(0)));
            black_box(c.cycle_samples(black_box([0; 3]), black_box(0)));
            {
                let (mut up, ap) = c.split();
                let _ = black_box(up.on_raw(black_box(0), black_box(0), black_box(0)));
                // Through `counting`, whose cycle is `Applier::cycle` on the counters' advance: one
                // copy of the fast path covers both entries (an application links one of them).
                let mut counting = ap.counting(black_box([0; 3]));
                black_box(counting.cycle(black_box([0; 3]), black_box(0)));
            }
            c.prime_counters(black_box([0; 3]));
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
    eprintln!("panic-check is a link-time check for thumbv7em-none-eabihf: run `cargo xtask panic-check`");
    std::process::exit(2);
}
