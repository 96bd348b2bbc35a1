//! tools/pds.py reads what the library writes and writes what it reads.

mod common;

use std::process::Command;

use common::*;
use pathdensity::dump::{DumpReader, Record};

#[test]
fn the_python_module_round_trips_dumps_with_the_library() {
    if !python_with_numpy() {
        common::skipped("python3 with numpy is not installed (.ci/run installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut h = header(5, 4, 2);
    h.scene = "héllo".into();
    h.seed = 42;
    let recs: Vec<Record> = (0..50)
        .map(|i| Record::new(i as f32 * 0.1, 3.5, 1.25, [i as f32, -2.0, 1e-30]))
        .collect();
    let a = write_dump(dir.path(), "a.pds", &h, &recs);
    let b = dir.path().join("b.pds");
    let script = format!(
        "import sys; sys.path.insert(0, 'tools'); import pds\n\
         h, r = pds.read({a:?})\n\
         assert h['scene'] == 'héllo' and h['seed'] == 42 and h['frames'] == 2, h\n\
         assert len(r) == 50 and float(r['x'][10]) == float(__import__('numpy').float32(1.0)), r[10]\n\
         pds.write({b:?}, r, width=5, height=4, frames=2, scene='héllo', seed=42, producer='tests')\n"
    );
    let st = Command::new("python3")
        .args(["-c", &script])
        .status()
        .unwrap();
    assert!(st.success());
    let d = DumpReader::open(&b).unwrap();
    assert_eq!(d.records(), &recs[..]);
    h.sample_count = 50;
    assert_eq!(d.header(), &h);
    // Byte for byte the same file as the library's writer.
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}
