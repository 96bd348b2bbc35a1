//! The `parallel` feature's sequential stand-in gives the same bytes: the
//! pipeline built without rayon (`pathdensity-core --no-default-features`)
//! and with it, on 2 threads, agree on every decision, count, image and
//! σ, for a pixel-major still and a pass-major animation.

use std::path::Path;
use std::process::Command;

use pathdensity::dump::Order;
use pathdensity::synth::SynthParams;

/// The digests `examples/run_bits.rs` prints for `dump`, built with or
/// without the `parallel` feature (in its own target directory, so this
/// test does not wait on the build lock of the run that started it).
fn digests(dump: &Path, parallel: bool) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut cmd = Command::new(env!("CARGO"));
    cmd.args(["run", "--quiet", "--release", "-p", "pathdensity-core"])
        .args(["--example", "run_bits"])
        .env("CARGO_TARGET_DIR", root.join("target/features"))
        .current_dir(root);
    if !parallel {
        cmd.arg("--no-default-features");
    }
    let out = cmd.arg("--").arg(dump).arg("2").output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn the_sequential_stand_in_gives_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    for (name, frames, order) in [
        ("still", 1, Order::PixelMajor),
        ("anim", 3, Order::PassMajor),
    ] {
        let p = SynthParams {
            width: 40,
            height: 30,
            frames,
            spp: 16,
            order,
            firefly_fraction: 0.01,
            light: Some((10, 10, 2, 50.0)),
            ..SynthParams::default()
        };
        let dump = dir.path().join(format!("{name}.pds"));
        p.write(&dump).unwrap();
        let parallel = digests(&dump, true);
        assert!(parallel.lines().count() >= 14, "{parallel}");
        assert_eq!(parallel, digests(&dump, false), "{name}");
    }
}
