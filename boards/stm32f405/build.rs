//! For the bare-metal target only: the STM32F405 memory map (with a flash sector kept for the
//! coefficient table), the link scripts, and the table sector's image.
//!
//! The image is 1 024 bytes (`qfa_thermal::table::MAX_TABLE_BYTES`): a table encoded by the
//! root crate's own `Table::encode`, then erased-flash 0xFF. By default the table is a
//! fixture built below; `QFA_BOARD_TABLE=path/to/table.bin` embeds a calibrated one (the
//! wire bytes `qfa-lab` writes) instead, after checking it with `Table::decode`.

use std::{env, fs, path::PathBuf};

use qfa_thermal::table::{MAX_AXES, MAX_TABLE_BYTES};
use qfa_thermal::{AxisModel, BiasGrid, Extensions, ScaleFactor, Table};

/// STM32F405xG: 1 MiB of flash in sectors 0–3 (16 KiB), 4 (64 KiB), 5–11 (128 KiB), and
/// 128 KiB of contiguous SRAM (SRAM1 112 KiB + SRAM2 16 KiB; the 64 KiB CCM is not used).
/// Sector 11, the last, holds only the table, so it can be erased and rewritten without
/// touching the code.
const MEMORY_X: &str = "\
MEMORY
{
  /* Sectors 0-10: code and constants. */
  FLASH : ORIGIN = 0x08000000, LENGTH = 1024K - 128K
  /* Sector 11 (128 KiB, erased as one unit): the coefficient table only. */
  QFA_TABLE : ORIGIN = 0x080E0000, LENGTH = 128K
  RAM : ORIGIN = 0x20000000, LENGTH = 128K
}

SECTIONS
{
  .qfa_table : ALIGN(4)
  {
    KEEP(*(.qfa_table .qfa_table.*));
  } > QFA_TABLE
}
INSERT AFTER .rodata;
";

/// The rate window the board's compensator is built with (`Compensator<3, 32, 3, _>`).
const RATE_WINDOW: u16 = 32;

/// A placeholder 3-axis table: JB-KT8 #1's scale factor (Zhang et al. 2021, Eq. 15) and a
/// plausible bias (about 100 µg at 22 °C, 1.5 µg/°C) on a −40..80 °C grid. It validates,
/// so the board runs compensated out of the box; it is not a calibration of any sensor.
fn fixture() -> Table {
    let scale = ScaleFactor::JB_KT8_1;
    let mut table = Table {
        input: qfa_thermal::Input::PulseCounts,
        rate_window: RATE_WINDOW,
        axes: Default::default(),
        misalignment: None,
    };
    for axis in 0..MAX_AXES {
        let offset = 1.0e-4 + 2.0e-5 * axis as f32;
        let k0: Vec<f32> = (0..13).map(|i| offset + 1.5e-6 * (-40.0 + 10.0 * i as f32 - 22.0)).collect();
        let model = AxisModel {
            scale,
            bias: BiasGrid::single_valued(-40.0, 10.0, &k0),
            rate_limit_c_per_min: 2.0,
            ext: Extensions::default(),
        };
        table.axes.push(model).expect("MAX_AXES axes fit");
    }
    table
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=QFA_BOARD_TABLE");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    // The table image is written for the host too: the host tests decode it.
    write_table_image(&out);
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    // cortex-m-rt's link.x does `INCLUDE memory.x`: this board's map, on the link path.
    fs::write(out.join("memory.x"), MEMORY_X).expect("write memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}

fn write_table_image(out: &std::path::Path) {
    let mut image = vec![0xFF_u8; MAX_TABLE_BYTES];
    let len = match env::var_os("QFA_BOARD_TABLE") {
        Some(path) => {
            println!("cargo:rerun-if-changed={}", PathBuf::from(&path).display());
            let bytes = fs::read(&path).unwrap_or_else(|e| panic!("QFA_BOARD_TABLE={}: {e}", path.to_string_lossy()));
            let table = Table::decode(&bytes)
                .unwrap_or_else(|e| panic!("QFA_BOARD_TABLE={}: not a valid table: {e}", path.to_string_lossy()));
            assert_eq!(
                table.rate_window, RATE_WINDOW,
                "QFA_BOARD_TABLE: table fitted with rate window {}, the board uses {RATE_WINDOW}",
                table.rate_window
            );
            assert_eq!(table.axes.len(), MAX_AXES, "QFA_BOARD_TABLE: the board has 3 axes");
            assert!(bytes.len() <= MAX_TABLE_BYTES, "QFA_BOARD_TABLE: larger than the table slot");
            image[..bytes.len()].copy_from_slice(&bytes);
            bytes.len()
        }
        None => fixture().encode(&mut image).expect("the fixture table validates and fits").len(),
    };
    // `encode` wrote into the front of the image; the rest stays erased (0xFF).
    image[len..].fill(0xFF);
    fs::write(out.join("table_sector.bin"), &image).expect("write table_sector.bin");
}
