//! docs/format.md: the byte layout, strict reading, and one clear error per defect.

mod common;

use common::*;
use pathdensity::dump::{DumpReader, Header, Order, Record, data_offset};

fn valid_bytes(h: &Header, recs: &[Record]) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let p = write_dump(dir.path(), "d.pds", h, recs);
    std::fs::read(p).unwrap()
}

/// The error of opening `bytes` as a dump named `bad.pds`.
fn err_of(bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.pds");
    std::fs::write(&p, bytes).unwrap();
    match DumpReader::open(&p) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn header_bytes_follow_the_spec_layout() {
    let mut h = header(640, 480, 3);
    h.spp = 16;
    h.sample_count = 2;
    h.order = Order::PassMajor;
    h.scene = "ab".into();
    h.seed = 7;
    h.producer = "xyz".into();
    let recs = [Record::new(1.0, 2.0, 0.5, [0.1, 0.2, 0.3]); 2];
    let b = valid_bytes(&h, &recs);
    assert_eq!(&b[0..8], b"PDSDUMP1");
    assert_eq!(u32::from_le_bytes(b[8..12].try_into().unwrap()), 1);
    // 4 × u32 + u64 + u8 + (u64 + 2) + u64 + (u64 + 3)
    let header_len = 16 + 8 + 1 + 10 + 8 + 11;
    assert_eq!(
        u32::from_le_bytes(b[12..16].try_into().unwrap()),
        header_len
    );
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().unwrap());
    assert_eq!(
        [u32_at(16), u32_at(20), u32_at(24), u32_at(28)],
        [640, 480, 3, 16]
    );
    assert_eq!(u64_at(32), 2);
    assert_eq!(b[40], 2);
    assert_eq!(u64_at(41), 2);
    assert_eq!(&b[49..51], b"ab");
    assert_eq!(u64_at(51), 7);
    assert_eq!(u64_at(59), 3);
    assert_eq!(&b[67..70], b"xyz");
    let off = data_offset(header_len as usize);
    assert_eq!(off, 128);
    assert!(b[70..off].iter().all(|&z| z == 0));
    assert_eq!(b.len(), off + 48);
    assert_eq!(
        f32::from_le_bytes(b[off + 8..off + 12].try_into().unwrap()),
        0.5
    );
}

#[test]
fn a_dump_reads_back_what_was_written() {
    let h = header(4, 3, 2);
    let recs: Vec<Record> = (0..100)
        .map(|i| Record::new(i as f32 * 0.01, 1.0, 1.5, [i as f32, -1.0, 1e30]))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let p = write_dump(dir.path(), "d.pds", &h, &recs);
    let d = DumpReader::open(&p).unwrap();
    assert_eq!(d.records(), &recs[..]);
    assert_eq!(d.header().sample_count, 100);
    assert_eq!(d.header().frames, 2);
    let empty = write_dump(dir.path(), "e.pds", &h, &[]);
    assert!(DumpReader::open(empty).unwrap().records().is_empty());
}

#[test]
fn defects_are_errors_that_name_the_file_and_the_problem() {
    let h = header(4, 4, 1);
    let good = valid_bytes(&h, &[Record::new(1.0, 1.0, 0.0, [1.0; 3]); 3]);

    let mut b = good.clone();
    b[0] = b'X';
    assert!(err_of(&b).contains("magic"));

    let mut b = good.clone();
    b[8] = 2;
    assert!(err_of(&b).contains("version 2"));

    let mut b = good.clone();
    b[12..16].copy_from_slice(&65537u32.to_le_bytes());
    assert!(err_of(&b).contains("header_len 65537"));

    let e = err_of(&good[..good.len() - 1]);
    assert!(e.contains("bad.pds") && e.contains(&format!("{}", good.len() - 1)));
    assert!(
        e.contains(&format!("{}", good.len())),
        "names the expected size: {e}"
    );

    let mut b = good.clone();
    b.extend_from_slice(&[0; 24]);
    assert!(err_of(&b).contains("3 samples need"));

    // Non-zero padding.
    let mut b = good.clone();
    let hl = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    b[16 + hl] = 1;
    assert!(err_of(&b).contains("padding"));

    // A header_len longer than the encoded header: trailing bytes.
    let mut b = good.clone();
    b[12..16].copy_from_slice(&((hl + 1) as u32).to_le_bytes());
    assert!(err_of(&b).contains("decodes from"));

    // Unknown order byte.
    let mut b = good.clone();
    b[40] = 3;
    assert!(err_of(&b).contains("order 3"));

    assert!(err_of(b"PDS").contains("too short"));
}

#[test]
fn absurd_sizes_are_rejected_before_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let bytes_for = |h: &Header| h.prefix_bytes();
    let mut h = header(8192, 8193, 1);
    assert!(bytes_for(&h).unwrap_err().contains("2^26"));
    h = header(1, 1, (1 << 20) + 1);
    assert!(bytes_for(&h).unwrap_err().contains("2^20"));
    h = header(0, 1, 1);
    assert!(bytes_for(&h).is_err());
    // A header claiming 2^40 samples in a small file: size mismatch.
    let mut b = valid_bytes(&header(4, 4, 1), &[]);
    b[32..40].copy_from_slice(&(1u64 << 40).to_le_bytes());
    assert!(err_of(&b).contains("need"));
    // 24 × sample_count overflowing u64.
    b[32..40].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(err_of(&b).contains("overflow"));
    // Width × height overflowing the pixel limit, written by hand.
    let mut b = valid_bytes(&header(4, 4, 1), &[]);
    b[16..20].copy_from_slice(&u32::MAX.to_le_bytes());
    b[20..24].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(err_of(&b).contains("exceeds"));
    // A directory is not a dump.
    let e = DumpReader::open(dir.path()).err().unwrap().to_string();
    assert!(e.contains("not a regular file"), "{e}");
    let e = DumpReader::open(dir.path().join("missing.pds"))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("missing.pds"));
}
