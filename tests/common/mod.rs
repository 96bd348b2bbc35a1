//! Shared test helpers, and the oracle: a plain single-threaded replay of
//! docs/filter.md §2 by brute force, written independently of the library's indexes.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use pathdensity::dump::{DumpWriter, Header, Order, Record, Validity};
use pathdensity::joint::JointSpace;

pub const INVALID: u8 = 0;
pub const STREAM: u8 = 1;
pub const FINAL: u8 = 2;
pub const REJECTED: u8 = 3;

pub fn header(width: u32, height: u32, frames: u32) -> Header {
    Header {
        width,
        height,
        frames,
        spp: 0,
        sample_count: 0,
        order: Order::Unspecified,
        scene: "test".into(),
        seed: 0,
        producer: "tests".into(),
    }
}

/// Writes `records` as a dump under `dir`.
pub fn write_dump(dir: &Path, name: &str, h: &Header, records: &[Record]) -> PathBuf {
    let path = dir.join(name);
    let mut w = DumpWriter::create(&path, h.clone()).unwrap();
    w.push_all(records).unwrap();
    w.finish().unwrap();
    path
}

fn point(space: &JointSpace, r: &Record, animated: bool) -> Vec<f32> {
    if animated {
        space.point::<6>(r).to_vec()
    } else {
        space.point::<5>(r).to_vec()
    }
}

fn distance(p: &[f32], q: &[f32]) -> f64 {
    p.iter()
        .zip(q)
        .map(|(&a, &b)| (a as f64 - b as f64) * (a as f64 - b as f64))
        .fold(0.0, |s, t| s + t)
        .sqrt()
}

fn sigma_brute(q: &[f32], set: &[(Vec<f32>, usize)], skip: Option<usize>, k: usize) -> f64 {
    let mut d: Vec<f64> = set
        .iter()
        .enumerate()
        .filter(|(i, _)| Some(*i) != skip)
        .map(|(_, (p, _))| distance(p, q))
        .collect();
    if d.len() < k {
        return f64::INFINITY;
    }
    d.sort_by(f64::total_cmp);
    d[..k].iter().fold(0.0, |s, &v| s + v) / k as f64
}

/// The oracle: decisions (one byte per record) and the deciding σ (NaN
/// for invalid records), by brute force in file order.
pub fn oracle(records: &[Record], h: &Header, k: usize, space: &JointSpace) -> (Vec<u8>, Vec<f64>) {
    let mut dec = vec![INVALID; records.len()];
    let mut sig = vec![f64::NAN; records.len()];
    let mut t: Vec<(Vec<f32>, usize)> = Vec::new();
    for (i, r) in records.iter().enumerate() {
        if r.validity(h) != Validity::Valid {
            continue;
        }
        let p = point(space, r, h.frames > 1);
        let s = sigma_brute(&p, &t, None, k);
        sig[i] = s;
        if s < 1.0 {
            dec[i] = STREAM;
        } else {
            dec[i] = REJECTED;
            t.push((p, i));
        }
    }
    for j in 0..t.len() {
        let s = sigma_brute(&t[j].0, &t, Some(j), k);
        let i = t[j].1;
        sig[i] = s;
        if s < 1.0 {
            dec[i] = FINAL;
        }
    }
    (dec, sig)
}

/// A deterministic pseudo-random stream for building test dumps.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The mean image of a synthetic dump (dense and firefly-free, it serves
/// as a reference).
pub fn synth_mean(p: &pathdensity::synth::SynthParams) -> pathdensity::recon::Image {
    use pathdensity::recon::{Film, ReconFilter};
    let h = p.header();
    let mut film = Film::new(&h, ReconFilter::Box);
    let mut occ = vec![0u32; h.pixels() * h.frames as usize];
    for r in p.records() {
        film.splat(&r);
        occ[r.pixel_index(&h)] += 1;
    }
    film.resolve(&occ)
}

/// `summary.csv` without the columns that depend on the run (status,
/// seconds).
pub fn deterministic_csv(out: &Path) -> String {
    let text = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&i| header[i] != "status" && !header[i].ends_with("_seconds"))
        .collect();
    let pick = |line: &str| {
        let cells: Vec<&str> = line.split(',').collect();
        keep.iter().map(|&i| cells[i]).collect::<Vec<_>>().join(",")
    };
    std::iter::once(pick(&header.join(",")))
        .chain(lines.map(pick))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Says loudly that a test skipped part of its work: written straight to
/// the process's stderr, which the test harness does not capture, so the
/// line shows even when the test passes.
pub fn skipped(why: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "SKIPPED: {why}");
}

/// An optional tool is missing: a loud skip, or, with the environment
/// variable `require` set (`.ci/run` sets every one), a failure.
pub fn missing<T>(require: &str, why: &str) -> Option<T> {
    if std::env::var_os(require).is_some() {
        panic!("{why}, and {require} is set");
    }
    skipped(why);
    None
}

/// The python of `tools/TOOL/.venv`, if `probe` (Python code) runs in it.
pub fn venv_python(tool: &str, probe: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tools")
        .join(tool)
        .join(".venv/bin/python");
    let ok = std::process::Command::new(&p)
        .args(["-c", probe])
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(p)
}

/// tools/oidn/.venv's python and the folder of the pyoidn wheel's OIDN
/// library (for `OIDN_DIR`), if tools/oidn/setup.sh has run; else a loud
/// skip, or a failure under `PATHDENSITY_REQUIRE_OIDN`.
#[allow(dead_code)]
pub fn oidn() -> Option<(PathBuf, String)> {
    let probe = "import os, pyoidn; print(os.path.join(os.path.dirname(pyoidn.__file__), 'oidn'))";
    let py = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/oidn/.venv/bin/python");
    let found = std::process::Command::new(&py)
        .args(["-c", probe])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    match found {
        Some(dir) => Some((py, dir)),
        None => missing(
            "PATHDENSITY_REQUIRE_OIDN",
            "OIDN is not set up (bash tools/oidn/setup.sh)",
        ),
    }
}

/// Whether `python3` can import numpy; with `PATHDENSITY_REQUIRE_NUMPY`
/// set (CI sets it) its absence fails the test instead of skipping it.
pub fn python_with_numpy() -> bool {
    let found = std::process::Command::new("python3")
        .args(["-c", "import numpy"])
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if !found && std::env::var_os("PATHDENSITY_REQUIRE_NUMPY").is_some() {
        panic!("python3 cannot import numpy, and PATHDENSITY_REQUIRE_NUMPY is set");
    }
    found
}

/// The image named `name` (`mean`, `filtered+oidn`), for the maps of a report.
#[allow(dead_code)]
pub fn image(name: &str) -> pathdensity::method::ImageId {
    name.parse().unwrap()
}

/// The JSON an HTML page embeds for its HDR viewer.
#[allow(dead_code)]
pub fn viewer_data(html: &str) -> serde_json::Value {
    let json = html
        .split("<script type=\"application/json\" id=\"viewer-data\">")
        .nth(1)
        .and_then(|s| s.split("</script>").next())
        .expect("the viewer's data");
    serde_json::from_str(json).unwrap()
}

/// The names of the viewer's images, in its order.
#[allow(dead_code)]
pub fn viewer_names(data: &serde_json::Value) -> Vec<&str> {
    data["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["name"].as_str().unwrap())
        .collect()
}
