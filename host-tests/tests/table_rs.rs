//! `qfa-lab table-rs` writes a table as the Rust source of a `static` in flash. Its output
//! for the reference vectors' every-slot table is checked in beside this file (the lab's
//! `table_rs` test regenerates it and fails on any difference); here it is compiled, and the
//! `static` must be exactly the table its wire bytes decode to, every bit of every number.

use qfa_thermal::Table;

include!("generated/ext_all_table.rs");

#[test]
fn the_generated_static_is_the_table_its_bytes_decode_to() {
    let bytes = include_bytes!("../fuzz-corpus/table/ext_all_valid.bin");
    let decoded = Table::decode(bytes).expect("the vectors' table decodes");
    assert_eq!(EXT_ALL, decoded);
    // Bit for bit, not only `==` on floats (which would take -0.0 for 0.0).
    let mut a = [0u8; qfa_thermal::table::MAX_TABLE_BYTES];
    let mut b = [0u8; qfa_thermal::table::MAX_TABLE_BYTES];
    assert_eq!(EXT_ALL.encode(&mut a).unwrap(), decoded.encode(&mut b).unwrap());
    // Every slot is on in it, so every part of the generator is compiled here.
    assert!(EXT_ALL
        .axes
        .iter()
        .all(|a| a.ext.sensor_lag.is_some() && a.ext.bias_branch_hysteresis.is_some() && a.ext.bias_creep.is_some()));
}
