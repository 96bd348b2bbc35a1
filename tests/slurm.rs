//! docs/farm.md's Slurm recipe under a real single-node Slurm
//! (tools/farm/slurm_local.sh): an array of four tasks over a dozen dumps,
//! one task pre-empted mid-dump with SIGTERM and requeued, then `--merge`,
//! gives the summary of one uninterrupted batch, and every output folder
//! is one whole run.
//!
//! Needs slurm-wlm and munge installed and root or password-less sudo;
//! skipped loudly without them, unless `PATHDENSITY_REQUIRE_SLURM` is set
//! (CI sets it and installs them) and the test fails instead.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_pathdensity");
const TASKS: usize = 4;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A Slurm started by tools/farm/slurm_local.sh in its own state folder;
/// stopped (daemons killed, state removed) when dropped, even on failure.
struct Slurm {
    state: PathBuf,
}

impl Slurm {
    fn script(state: &Path, what: &str) -> Output {
        Command::new("bash")
            .arg(root().join("tools/farm/slurm_local.sh"))
            .arg(what)
            .env("PATHDENSITY_SLURM_DIR", state)
            // The test does not install packages: .ci/run does.
            .env("PATHDENSITY_SLURM_INSTALL", "0")
            .output()
            .unwrap()
    }

    /// Starts it, or says why it could not (skipping the test, or failing
    /// it with `PATHDENSITY_REQUIRE_SLURM` set).
    fn start() -> Option<Slurm> {
        let state =
            std::env::temp_dir().join(format!("pathdensity-slurm-test-{}", std::process::id()));
        let t0 = Instant::now();
        let o = Self::script(&state, "start");
        if !o.status.success() {
            let why = format!(
                "no local Slurm (bash tools/farm/slurm_local.sh start: {})",
                text(&o).trim()
            );
            let _ = Self::script(&state, "stop");
            if std::env::var_os("PATHDENSITY_REQUIRE_SLURM").is_some() {
                panic!("{why}, and PATHDENSITY_REQUIRE_SLURM is set");
            }
            common::skipped(&format!("{why}: the Slurm recipe is not run under Slurm"));
            return None;
        }
        note(&format!(
            "started in {:.1} s ({})",
            t0.elapsed().as_secs_f64(),
            text(&o).trim()
        ));
        Some(Slurm { state })
    }

    fn conf(&self) -> PathBuf {
        self.state.join("slurm.conf")
    }

    fn cmd(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", self.conf());
        c
    }

    fn ok(&self, program: &str, args: &[&str]) -> String {
        let o = self.cmd(program).args(args).output().unwrap();
        assert!(
            o.status.success(),
            "{program} {args:?}: {}: {}",
            o.status,
            text(&o)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    }

    /// `scontrol show job` of one array task, as KEY=VALUE pairs.
    fn job(&self, id: &str) -> Vec<(String, String)> {
        self.ok("scontrol", &["-o", "show", "job", id])
            .split_whitespace()
            .filter_map(|kv| kv.split_once('='))
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect()
    }

    fn field(&self, id: &str, key: &str) -> String {
        self.job(id)
            .into_iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v)
            .unwrap_or_else(|| panic!("no {key} in scontrol show job {id}"))
    }

    fn log_tail(&self) -> String {
        let mut s = String::new();
        for f in ["slurmctld.log", "slurmd.log"] {
            let t = std::fs::read_to_string(self.state.join(f)).unwrap_or_default();
            let lines: Vec<&str> = t.lines().collect();
            s += &format!(
                "--- {f}\n{}\n",
                lines[lines.len().saturating_sub(10)..].join("\n")
            );
        }
        s
    }
}

impl Drop for Slurm {
    fn drop(&mut self) {
        let o = Self::script(&self.state, "stop");
        if !o.status.success() {
            note(&format!("slurm_local.sh stop: {}", text(&o)));
        }
    }
}

/// A timing line, shown even when the test passes (straight to stderr,
/// which the harness does not capture).
fn note(line: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "slurm: {line}");
}

fn wait_until(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !done() {
        assert!(
            t0.elapsed() < timeout,
            "timed out ({timeout:?}) waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn staging(out: &Path, stem: &str) -> Vec<String> {
    std::fs::read_dir(out)
        .map(|d| {
            d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with(&format!(".{stem}.")) && n.ends_with(".staging"))
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn the_slurm_recipe_survives_a_preempted_requeued_task() {
    let t0 = Instant::now();
    let Some(slurm) = Slurm::start() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let shots = dir.path().join("shots");
    std::fs::create_dir_all(&shots).unwrap();
    let synth = |name: &str, side: u32, seed: u32| {
        let side = side.to_string();
        let o = Command::new(BIN)
            .arg("synth")
            .arg("-o")
            .arg(shots.join(format!("{name}.pds")))
            .args(["--width", &side, "--height", &side, "--spp", "32"])
            .args(["--seed", &seed.to_string()])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", text(&o));
    };
    for seed in 1..=11 {
        synth(&format!("s{seed:02}"), 48, seed);
    }
    // 4.7 M samples: about 4 s to filter on 2 threads (0.1 s for a small one),
    // long enough to be pre-empted mid-dump.
    synth("big", 384, 100);
    let pattern = format!("{}/*.pds", shots.display());

    // One uninterrupted batch: what the array must reproduce.
    let one = dir.path().join("one");
    let t = Instant::now();
    let o = Command::new(BIN)
        .args(["batch", &pattern, "-o", one.to_str().unwrap(), "--no-html"])
        .args(["--threads", "2"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    note(&format!(
        "one batch of the 12 dumps in {:.1} s",
        t.elapsed().as_secs_f64()
    ));

    let out = dir.path().join("out");
    let bin_dir = Path::new(BIN).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let array = format!("--array=0-{}", TASKS - 1);
    let o = slurm
        .cmd("sbatch")
        .args(["--parsable", &array])
        .arg(root().join("tools/farm/slurm_array.sh"))
        .args([&pattern, out.to_str().unwrap(), "--no-html"])
        .current_dir(dir.path())
        .env("PATH", &path)
        .output()
        .unwrap();
    assert!(o.status.success(), "sbatch: {}", text(&o));
    let job = String::from_utf8_lossy(&o.stdout)
        .trim()
        .split(';')
        .next()
        .unwrap()
        .to_owned();
    let task = |i: usize| format!("{job}_{i}");
    let queued = || !slurm.ok("squeue", &["-h", "-j", &job]).trim().is_empty();

    // Pre-empt the task filtering the big dump while it runs: once its
    // staging folder is there and that task is the only one running.
    let t = Instant::now();
    let mut victim = String::new();
    wait_until(
        "the big dump to start under a sole running task",
        Duration::from_secs(120),
        || {
            assert!(
                queued(),
                "the array ended before the big dump could be pre-empted"
            );
            if staging(&out, "big").is_empty() {
                return false;
            }
            let running = slurm.ok("squeue", &["-h", "-j", &job, "-t", "RUNNING", "-o", "%i"]);
            let running: Vec<&str> = running.split_whitespace().collect();
            if running.len() == 1 {
                victim = running[0].to_owned();
            }
            running.len() == 1
        },
    );
    // `--batch`: without it scancel signals only the job's steps, and the
    // recipe has none (the batch script execs pathdensity).
    // scancel's own status is no guide: the signal is delivered, the task
    // ends at once, and scancel, retrying on the "transitional state" of a
    // completing job, then reports it completed (exit 1 or 229). What the
    // task did is checked below.
    let signalled = t.elapsed();
    let o = slurm
        .cmd("scancel")
        .args(["--signal=TERM", "--batch", &victim])
        .output()
        .unwrap();
    note(&format!("scancel: {}: {}", o.status, text(&o).trim()));
    wait_until(
        "the pre-empted task to end",
        Duration::from_secs(60),
        || {
            !matches!(
                slurm.field(&victim, "JobState").as_str(),
                "RUNNING" | "COMPLETING"
            )
        },
    );
    // It was interrupted mid-dump: pathdensity's SIGTERM exit status, no
    // output folder for the big dump, and its staging folder removed.
    assert_eq!(
        slurm.field(&victim, "JobState"),
        "FAILED",
        "{:?}",
        slurm.job(&victim)
    );
    assert_eq!(slurm.field(&victim, "ExitCode"), "130:0");
    assert!(
        !out.join("big").exists(),
        "the big dump was done before SIGTERM"
    );
    assert!(
        staging(&out, "big").is_empty(),
        "{:?}",
        staging(&out, "big")
    );
    note(&format!(
        "task {victim} pre-empted {:.1} s after its big dump started",
        signalled.as_secs_f64()
    ));

    slurm.ok("scontrol", &["requeue", &victim]);
    assert_eq!(slurm.field(&victim, "Restarts"), "1");
    let t = Instant::now();
    wait_until("the array to finish", Duration::from_secs(300), || {
        !queued()
    });
    note(&format!(
        "array done {:.1} s after the requeue",
        t.elapsed().as_secs_f64()
    ));
    for i in 0..TASKS {
        let id = task(i);
        assert_eq!(
            slurm.field(&id, "JobState"),
            "COMPLETED",
            "{id}: {:?}\n{}",
            slurm.job(&id),
            slurm.log_tail()
        );
        assert_eq!(slurm.field(&id, "ExitCode"), "0:0", "{id}");
        let restarts = if id == victim { "1" } else { "0" };
        assert_eq!(slurm.field(&id, "Restarts"), restarts, "{id}");
        // The log keeps both attempts (--open-mode=append): Slurm's line
        // for the signal, then one whole run's summary line.
        let log =
            std::fs::read_to_string(dir.path().join(format!("pathdensity-{id}.log"))).unwrap();
        let runs = log
            .lines()
            .filter(|l| l.starts_with(&format!("batch {i}/{TASKS}:")))
            .count();
        assert_eq!(runs, 1, "{id}: {log}");
        assert_eq!(log.contains("CANCELLED"), id == victim, "{id}: {log}");
    }

    let o = Command::new(BIN)
        .args(["batch", "--merge", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        common::deterministic_csv(&out),
        common::deterministic_csv(&one)
    );

    // Every output folder is one complete run, and nothing hidden is left.
    let mut folders = 0;
    for e in std::fs::read_dir(&out).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        assert!(!name.ends_with(".staging"), "{name} left behind");
        if !e.path().is_dir() {
            continue;
        }
        folders += 1;
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(e.path().join("report.json")).unwrap()).unwrap();
        for f in report["outputs"].as_array().unwrap() {
            assert!(e.path().join(f.as_str().unwrap()).is_file(), "{name}/{f}");
        }
    }
    assert_eq!(folders, 12);
    note(&format!("test done in {:.1} s", t0.elapsed().as_secs_f64()));
}
