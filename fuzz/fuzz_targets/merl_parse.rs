//! The MERL `.binary` reader on arbitrary bytes: an error value or a table, never a panic; a table it
//! accepts is written back to the same bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nbrdf::measured::MerlTable;

fuzz_target!(|data: &[u8]| {
    if let Ok(table) = MerlTable::from_bytes(data) {
        assert_eq!(table.to_bytes(), data);
    }
});
