//! `pathdensity import`: image sequences, numpy arrays and BCD raw files
//! become valid dumps holding exactly their samples; bad input gets one line
//! naming the file, exit code 1 and no dump.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use pathdensity::dump::{DumpReader, Order, Record};
use pathdensity::image::Image;
use pathdensity::io::exr;

fn pathdensity(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathdensity"))
        .args(args)
        .output()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A W × H image whose pixel p of image k is (k, p, −p).
fn write_image(dir: &Path, name: &str, w: usize, h: usize, k: usize) -> PathBuf {
    let mut img = Image::new(w, h, 1);
    for (p, px) in img.data.iter_mut().enumerate() {
        *px = [k as f64, p as f64, -(p as f64)];
    }
    exr::write_image(dir, name, &img).unwrap();
    dir.join(format!("{name}.exr"))
}

/// A numpy .npy (format 1.0) of the given header dictionary and bytes.
fn write_npy(path: &Path, dict: &str, data: &[u8]) {
    let mut header = dict.to_string();
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(data);
    std::fs::write(path, bytes).unwrap();
}

fn f32_bytes(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// Exit code 1, one line naming `file` and containing `expected`, no dump.
fn refused(o: Output, file: &Path, expected: &str, out: &Path) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains(s(file)) && err.contains(expected), "{err}");
    assert!(!out.exists(), "{} was written", out.display());
}

#[test]
fn an_image_sequence_becomes_a_pass_major_dump_at_pixel_centres() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (5, 3);
    let images: Vec<PathBuf> = (0..4)
        .map(|k| write_image(dir.path(), &format!("seed{k}"), w, h, k))
        .collect();
    let out = dir.path().join("seq.pds");
    let mut args = vec!["import", "images"];
    args.extend(images.iter().map(|p| s(p)));
    args.extend(["-o", s(&out)]);
    let o = pathdensity(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        String::from_utf8_lossy(&o.stdout)
            .contains("60 records (5 × 3, 4 spp, pass-major), all valid")
    );
    let d = DumpReader::open(&out).unwrap();
    assert_eq!(
        (d.header().spp, d.header().order, d.header().frames),
        (4, Order::PassMajor, 1)
    );
    for (i, r) in d.records().iter().enumerate() {
        let (k, p) = (i / (w * h), i % (w * h));
        let want = Record::new(
            (p % w) as f32 + 0.5,
            (p / w) as f32 + 0.5,
            0.0,
            [k as f32, p as f32, -(p as f32)],
        );
        assert_eq!(*r, want, "record {i}");
    }
}

#[test]
fn a_bad_image_sequence_is_refused_naming_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let a = write_image(dir.path(), "a", 5, 3, 0);
    let small = write_image(dir.path(), "small", 4, 3, 1);
    let text = dir.path().join("notes.exr");
    std::fs::write(&text, "not an image").unwrap();
    let missing = dir.path().join("missing.exr");
    let out = dir.path().join("out.pds");
    for (bad, expected) in [
        (&small, "every image must have the same size"),
        (&text, "cannot read EXR"),
        (&missing, "No such file"),
    ] {
        refused(
            pathdensity(&["import", "images", s(&a), s(bad), "-o", s(&out)]),
            bad,
            expected,
            &out,
        );
    }
}

#[test]
fn a_numpy_array_becomes_a_dump_of_its_rows() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<[f32; 6]> = (0..24)
        .map(|i| {
            [
                (i % 4) as f32 + 0.25,
                (i / 8) as f32 + 0.75,
                0.0,
                i as f32,
                1.0,
                if i == 7 { f32::NAN } else { 2.0 },
            ]
        })
        .collect();
    let npy = dir.path().join("samples.npy");
    write_npy(
        &npy,
        "{'descr': '<f4', 'fortran_order': False, 'shape': (24, 6), }",
        &f32_bytes(rows.iter().flatten().copied()),
    );
    let out = dir.path().join("n.pds");
    let o = pathdensity(&[
        "import",
        "npy",
        s(&npy),
        "--width",
        "4",
        "--height",
        "3",
        "--spp",
        "2",
        "--order",
        "pixel",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("1 invalid (non-finite 1"),
        "{o:?}"
    );
    let d = DumpReader::open(&out).unwrap();
    assert_eq!(
        (d.header().width, d.header().height, d.header().spp),
        (4, 3, 2)
    );
    assert_eq!(d.header().order, Order::PixelMajor);
    assert_eq!(d.header().scene, "samples");
    for (r, want) in d.records().iter().zip(&rows) {
        assert_eq!(bytemuck::bytes_of(r), bytemuck::bytes_of(want));
    }
    assert_eq!(d.records().len(), 24);
}

#[test]
fn numpy_arrays_of_the_wrong_kind_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pds");
    let data = f32_bytes((0..24).map(|i| i as f32));
    let cases: [(&str, &str, Vec<u8>, &str); 6] = [
        (
            "f8.npy",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 6), }",
            data.repeat(2),
            "dtype",
        ),
        (
            "five.npy",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (4, 5), }",
            data[..80].to_vec(),
            "shape (4, 5)",
        ),
        (
            "flat.npy",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (24,), }",
            data.clone(),
            "shape (24,)",
        ),
        (
            "fortran.npy",
            "{'descr': '<f4', 'fortran_order': True, 'shape': (4, 6), }",
            data.clone(),
            "Fortran order",
        ),
        (
            "short.npy",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (5, 6), }",
            data.clone(),
            "need",
        ),
        (
            "count.npy",
            "{'descr': '<f4', 'fortran_order': False, 'shape': (4, 6), }",
            data.clone(),
            "3 spp",
        ),
    ];
    for (name, dict, bytes, expected) in cases {
        let p = dir.path().join(name);
        write_npy(&p, dict, &bytes);
        let o = pathdensity(&[
            "import",
            "npy",
            s(&p),
            "--width",
            "2",
            "--height",
            "1",
            "--spp",
            "3",
            "-o",
            s(&out),
        ]);
        refused(o, &p, expected, &out);
    }
    let not = dir.path().join("not.npy");
    std::fs::write(&not, "x, y, t, r, g, b\n").unwrap();
    refused(
        pathdensity(&[
            "import",
            "npy",
            s(&not),
            "--width",
            "2",
            "--height",
            "1",
            "-o",
            s(&out),
        ]),
        &not,
        "not a numpy",
        &out,
    );
}

#[test]
fn numpys_own_files_import() {
    if !common::python_with_numpy() {
        common::skipped("python3 with numpy is not installed (.ci/run installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let npy = dir.path().join("np.npy");
    let script = format!(
        "import numpy as np\n\
         a = np.zeros((6, 6), np.float32); a[:, 0] = 0.5; a[:, 1] = np.arange(6) / 2; a[:, 3] = np.arange(6)\n\
         np.save({:?}, a)\n",
        s(&npy)
    );
    assert!(
        Command::new("python3")
            .args(["-c", &script])
            .status()
            .unwrap()
            .success()
    );
    let out = dir.path().join("np.pds");
    let o = pathdensity(&[
        "import",
        "npy",
        s(&npy),
        "--width",
        "1",
        "--height",
        "3",
        "--spp",
        "2",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = DumpReader::open(&out).unwrap();
    let r: Vec<f32> = d.records().iter().map(|r| r.rgb()[0]).collect();
    assert_eq!(r, [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
    assert_eq!(d.records()[3].y, 1.5);
}

fn bcd_file(path: &Path, header: [i32; 5], floats: usize) {
    let mut bytes: Vec<u8> = header.iter().flat_map(|v| v.to_le_bytes()).collect();
    bytes.extend(f32_bytes((0..floats).map(|i| i as f32)));
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn a_bcd_raw_file_becomes_a_pixel_major_dump() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h, spp) = (3, 2, 4);
    for channels in [3, 4] {
        let raw = dir.path().join(format!("c{channels}.raw"));
        bcd_file(
            &raw,
            [1, w, h, spp, channels],
            (w * h * spp * channels) as usize,
        );
        let out = dir.path().join(format!("c{channels}.pds"));
        let o = pathdensity(&["import", "bcd", s(&raw), "-o", s(&out)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let d = DumpReader::open(&out).unwrap();
        assert_eq!((d.header().spp, d.header().order), (4, Order::PixelMajor));
        for (i, r) in d.records().iter().enumerate() {
            let p = i / spp as usize;
            let first = (i * channels as usize) as f32;
            let want = Record::new(
                (p % 3) as f32 + 0.5,
                (p / 3) as f32 + 0.5,
                0.0,
                [first, first + 1.0, first + 2.0],
            );
            assert_eq!(*r, want, "record {i}");
        }
    }
}

#[test]
fn bad_bcd_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pds");
    let cases: [([i32; 5], usize, &str); 4] = [
        ([1, 3, 2, 4, 3], 3 * 2 * 4 * 3 - 1, "truncated"),
        (
            [1, 3, 2, 4, 3],
            3 * 2 * 4 * 3 + 1,
            "longer than its header says",
        ),
        ([1, 3, 2, 4, 5], 3 * 2 * 4 * 5, "5 channels"),
        ([1, -3, 2, 4, 3], 0, "not a BCD raw file"),
    ];
    for (i, (header, floats, expected)) in cases.into_iter().enumerate() {
        let raw = dir.path().join(format!("bad{i}.raw"));
        bcd_file(&raw, header, floats);
        refused(
            pathdensity(&["import", "bcd", s(&raw), "-o", s(&out)]),
            &raw,
            expected,
            &out,
        );
    }
    let tiny = dir.path().join("tiny.raw");
    std::fs::write(&tiny, [1, 2, 3]).unwrap();
    refused(
        pathdensity(&["import", "bcd", s(&tiny), "-o", s(&out)]),
        &tiny,
        "too short",
        &out,
    );
}
