//! The table slot: `MAX_TABLE_BYTES` (1 024) bytes of flash holding one encoded table
//! (16-byte header + postcard payload), then erased 0xFF.

use qfa_thermal::table::{self, Table, HEADER_LEN, MAX_TABLE_BYTES};

/// The encoded table within `slot`: the header's payload length bounds the slice (capped
/// at the slot), since `Table::decode` refuses trailing bytes. Whatever the slot holds, the
/// decode that follows gives a typed error, never a table it did not validate.
#[must_use]
pub fn encoded(slot: &[u8; MAX_TABLE_BYTES]) -> &[u8] {
    let payload = u32::from_le_bytes([slot[8], slot[9], slot[10], slot[11]]) as usize;
    &slot[..HEADER_LEN.saturating_add(payload).min(MAX_TABLE_BYTES)]
}

/// Decode and validate the table in `slot`.
///
/// # Errors
/// The `table::Error` of `Table::decode`: `BadMagic` for an erased slot, `Truncated` for
/// a length past the slot, `Crc` for a corrupted payload, and so on.
pub fn decode(slot: &[u8; MAX_TABLE_BYTES]) -> table::Result<Table> {
    Table::decode(encoded(slot))
}

#[cfg(test)]
mod tests {
    use super::*;
    use qfa_thermal::{Compensator, Config, Status};

    /// The image build.rs wrote, the same bytes the target links into sector 11.
    const IMAGE: &[u8; MAX_TABLE_BYTES] = include_bytes!(concat!(env!("OUT_DIR"), "/table_sector.bin"));

    #[test]
    fn the_built_image_loads_into_the_boards_compensator() {
        let table: &'static Table = Box::leak(Box::new(decode(IMAGE).expect("the image decodes")));
        let mut comp = Compensator::<3, 32, 3, &'static Table>::new(Config::default()).expect("default config");
        assert!(comp.status().contains(Status::NO_TABLE));
        comp.set_table(table).expect("rate window and axis count match the board");
        assert!(!comp.status().contains(Status::NO_TABLE));
        // Independent of `encoded`: the slot past the table is erased flash.
        let len = encoded(IMAGE).len();
        assert!(len > HEADER_LEN && IMAGE[len..].iter().all(|&b| b == 0xFF), "table {len} B, then 0xFF");
        // Decoding the whole slot instead would see the erased bytes as trailing garbage.
        assert_eq!(Table::decode(IMAGE), Err(table::Error::TrailingBytes));
    }

    #[test]
    fn a_bad_slot_gives_a_typed_error() {
        assert_eq!(decode(&[0xFF; MAX_TABLE_BYTES]), Err(table::Error::BadMagic));
        let mut flipped = *IMAGE;
        flipped[HEADER_LEN + 5] ^= 0x01;
        assert_eq!(decode(&flipped), Err(table::Error::Crc));
        let mut long = *IMAGE;
        long[8..12].copy_from_slice(&(MAX_TABLE_BYTES as u32).to_le_bytes());
        assert_eq!(decode(&long), Err(table::Error::Truncated));
    }
}
