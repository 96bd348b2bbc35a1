//! The fuzz target's corpus and any crash reproducers, replayed on stable
//! as regression tests: parsing never panics, a parsed header is valid, and
//! every valid record falls inside the film. (`cargo +nightly fuzz run dump`
//! runs the fuzzer itself; see docs/ARCHITECTURE.md.)

use std::path::Path;

use pathdensity::dump::{Record, Validity, data_offset, parse_prefix};

fn replay(data: &[u8]) {
    let Ok((header, header_len)) = parse_prefix(data, data.len() as u64) else {
        return;
    };
    header.validate().expect("a parsed header is valid");
    let bins = header.pixels() * header.frames as usize;
    for chunk in data[data_offset(header_len)..].chunks_exact(24) {
        let r: Record = bytemuck::pod_read_unaligned(chunk);
        if r.validity(&header) == Validity::Valid {
            assert!(r.pixel_index(&header) < bins);
        }
    }
}

#[test]
fn the_fuzz_corpus_and_crash_reproducers_parse_without_panicking() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut n = 0;
    for sub in ["corpus/dump", "artifacts/dump"] {
        let Ok(rd) = std::fs::read_dir(root.join(sub)) else {
            continue;
        };
        for e in rd {
            let p = e.unwrap().path();
            replay(&std::fs::read(&p).unwrap());
            n += 1;
        }
    }
    assert!(n >= 3, "the corpus holds at least the seeds");
}

#[test]
fn prefixes_of_a_valid_dump_are_all_errors_not_panics() {
    let seed =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/dump/seed-2x2x1-2-pixel.pds");
    let bytes = std::fs::read(seed).unwrap();
    assert!(parse_prefix(&bytes, bytes.len() as u64).is_ok());
    for cut in 0..bytes.len() {
        let e = parse_prefix(&bytes[..cut], cut as u64);
        assert!(e.is_err(), "a dump cut at {cut} bytes parsed");
    }
}
