//! Fuzzes the dump reader: the prefix parser (magic, version, header_len,
//! bincode header, padding, size check) on arbitrary bytes, then the
//! record classification of whatever records follow a valid prefix.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pathdensity::dump::{Record, Validity, data_offset, parse_prefix};

fuzz_target!(|data: &[u8]| {
    let Ok((header, header_len)) = parse_prefix(data, data.len() as u64) else {
        return;
    };
    header.validate().expect("a parsed header is valid");
    let offset = data_offset(header_len);
    let bins = header.pixels() * header.frames as usize;
    for chunk in data[offset..].chunks_exact(24) {
        let r: Record = bytemuck::pod_read_unaligned(chunk);
        if r.validity(&header) == Validity::Valid {
            assert!(r.pixel_index(&header) < bins);
        }
    }
});
