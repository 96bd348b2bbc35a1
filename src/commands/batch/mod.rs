//! `pathdensity batch`: many dumps (or the frames of many shots) filtered
//! with one configuration into `OUTDIR/<name>/` each, exactly as `filter`
//! writes them, and one summary of them all (`summary.csv`, `.json`,
//! `.html`).
//!
//! - **Resumable**: a dump whose folder holds a complete run made from the
//!   same dump bytes, reference and configuration (the hashes in its
//!   `report.json`) is skipped; `force` redoes it. Each dump's folder is
//!   swapped in whole when its run ends, so an interrupted batch leaves no
//!   half-written output and the next run continues after the last dump
//!   done.
//! - **Sharded**: `--shard I/N` takes a share of the dumps that every
//!   process computes alike ([`shard::partition`]), writes
//!   `batch-shard-I-of-N.json` instead of the summary, and `merge` builds
//!   the summary once all N are there (docs/farm.md).
//! - **Bounded**: dumps run one after another, each memory-mapped only
//!   while it is filtered; what is kept between dumps is one small entry
//!   each.
//! - **Bad input stays in its row**: a dump that cannot be read or
//!   filtered fails its own entry, with the reason, and the batch goes on.

pub mod jobs;
pub mod shard;
pub mod summary;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

use anyhow::{Context, Result, bail};

use super::filter::{self, FilterOptions};
use crate::config::FilterConfig;
use crate::dump::{DumpReader, Record};
use crate::io::{atomic, exr, guard};
use crate::progress::Progress;
use jobs::{Inputs, Job};
use shard::Shard;
use summary::ReportDigest;

/// What to filter, how, and where.
#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// Dump paths or glob patterns.
    pub dumps: Vec<String>,
    /// A manifest: one dump a line with per-dump options ([`jobs::parse_manifest`]).
    pub manifest: Option<PathBuf>,
    pub out_dir: PathBuf,
    /// Shared by every dump (a manifest line may override fields).
    pub config: FilterConfig,
    /// Each dump's reference, `{dir}` and `{stem}` substituted.
    pub reference_pattern: Option<String>,
    /// Worker threads of each dump's filter; 0 means one per core.
    pub threads: usize,
    /// Each dump's previews and `report.html`, as `filter` writes them.
    pub html: bool,
    pub sigma_map: bool,
    pub shard: Shard,
    /// Filter every dump, up to date or not.
    pub force: bool,
}

impl BatchOptions {
    pub fn new(dumps: Vec<String>, out_dir: impl Into<PathBuf>) -> BatchOptions {
        BatchOptions {
            dumps,
            manifest: None,
            out_dir: out_dir.into(),
            config: FilterConfig::DEFAULT,
            reference_pattern: None,
            threads: 0,
            html: true,
            sigma_map: false,
            shard: Shard::WHOLE,
            force: false,
        }
    }
}

/// What became of one dump.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Filtered by this run.
    Filtered,
    /// Its outputs were complete and up to date.
    Skipped,
    /// It could not be filtered (the entry says why).
    Failed,
}

impl Status {
    pub fn name(self) -> &'static str {
        match self {
            Status::Filtered => "filtered",
            Status::Skipped => "skipped",
            Status::Failed => "failed",
        }
    }
}

/// One dump's line in a shard file and the summary.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Entry {
    pub name: String,
    pub dump: String,
    pub status: Status,
    /// Why it failed, or why it has no metrics (a missing reference).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub problem: Option<String>,
}

/// A batch run's entries, and the summary's path when it wrote one.
pub struct Outcome {
    pub entries: Vec<Entry>,
    pub summary: Option<PathBuf>,
}

impl Outcome {
    pub fn count(&self, s: Status) -> usize {
        self.entries.iter().filter(|e| e.status == s).count()
    }

    /// What the command prints: the counts, each failure, where to look.
    pub fn text(&self, shard: Shard) -> String {
        let mut s = format!(
            "batch {shard}: {} dumps: {} filtered, {} skipped (up to date), {} failed\n",
            self.entries.len(),
            self.count(Status::Filtered),
            self.count(Status::Skipped),
            self.count(Status::Failed)
        );
        for e in &self.entries {
            if let Some(p) = &e.problem {
                s += &format!("  {}: {p}\n", e.name);
            }
        }
        match &self.summary {
            Some(p) => s += &format!("summary: {}\n", p.display()),
            None => s += "summary: when every shard is done, `pathdensity batch --merge OUTDIR`\n",
        }
        s
    }
}

/// Runs this process's share of the batch. Errors are the batch's own
/// (no dump to filter, a bad manifest, an unwritable OUTDIR); a dump's
/// problems go into its entry.
pub fn batch(opts: &BatchOptions, progress: &dyn Progress) -> Result<Outcome> {
    opts.config.validate()?;
    let all = jobs::collect(&Inputs {
        dumps: &opts.dumps,
        manifest: opts.manifest.as_deref(),
        config: &opts.config,
        reference_pattern: opts.reference_pattern.as_deref(),
    })?;
    let sizes: Vec<u64> = all
        .iter()
        .map(|j| std::fs::metadata(&j.dump).map_or(0, |m| m.len()))
        .collect();
    let keyed: Vec<(&str, u64)> = all
        .iter()
        .map(|j| j.name.as_str())
        .zip(sizes.iter().copied())
        .collect();
    let shards = shard::partition(&keyed, opts.shard.count);
    let mine: Vec<(&Job, u64)> = all
        .iter()
        .zip(&sizes)
        .zip(&shards)
        .filter(|&(_, &s)| s == opts.shard.index)
        .map(|((j, &size), _)| (j, size))
        .collect();
    // OUTDIR is never replaced whole (it may hold the dumps), but the
    // summaries and shard files it gets replace only files of ours.
    guard::check_ours(&opts.out_dir)?;
    std::fs::create_dir_all(&opts.out_dir)
        .with_context(|| format!("{}: cannot create", opts.out_dir.display()))?;
    if !opts.out_dir.join(guard::MARKER).exists() {
        guard::write_marker::<&str>(&opts.out_dir, &[])?;
    }

    // No dump's folder may hold any dump or reference of the batch.
    let protect = Arc::new(guard::Inputs::of(
        all.iter()
            .flat_map(|j| std::iter::once(&j.dump).chain(&j.reference)),
    ));
    let samples = |size: u64| size / std::mem::size_of::<Record>() as u64;
    progress.set_length(mine.iter().map(|&(_, size)| samples(size)).sum());
    let mut entries: Vec<Entry> = Vec::with_capacity(mine.len());
    for (job, size) in mine {
        let within = Within::new(progress);
        let entry = run_job(job, opts, &protect, &within);
        if entry.status != Status::Filtered {
            // A skipped or failed dump's samples count once, whatever its
            // replay counted before it stopped.
            progress.inc(samples(size).saturating_sub(within.counted()));
        }
        entries.push(entry);
        let n = |s| entries.iter().filter(|e| e.status == s).count();
        progress.message(&format!(
            "{} done, {} skipped, {} failed",
            n(Status::Filtered),
            n(Status::Skipped),
            n(Status::Failed)
        ));
    }
    progress.finish();

    if opts.shard == Shard::WHOLE {
        let path = summary::write(&opts.out_dir, &entries)?;
        return Ok(Outcome {
            entries,
            summary: Some(path),
        });
    }
    let file = ShardFile {
        shard: opts.shard,
        batch_xxh3: batch_hash(&all),
        entries: entries.clone(),
    };
    let json = serde_json::to_vec_pretty(&file).expect("a shard file serialises");
    atomic::write_bytes(&opts.out_dir.join(file.file_name()), &json)?;
    Ok(Outcome {
        entries,
        summary: None,
    })
}

/// Builds the summary of a sharded batch from its shards' files, once
/// every shard has written its own.
pub fn merge(out_dir: &Path) -> Result<Outcome> {
    let mut files: Vec<ShardFile> = Vec::new();
    let listing = std::fs::read_dir(out_dir).with_context(|| format!("{}", out_dir.display()))?;
    for e in listing {
        let path = e.with_context(|| format!("{}", out_dir.display()))?.path();
        let is_shard = path
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with("batch-shard-") && n.ends_with(".json"));
        if is_shard {
            let text = guard::read_input(&path, SHARD_FILE_LIMIT)?;
            let f: ShardFile = serde_json::from_slice(&text)
                .map_err(|e| anyhow::anyhow!("{}: not a shard file: {e}", path.display()))?;
            files.push(f);
        }
    }
    let Some(first) = files.first() else {
        bail!(
            "{}: no batch-shard-*.json: run `batch --shard I/N` first",
            out_dir.display()
        );
    };
    let (count, hash) = (first.shard.count, first.batch_xxh3.clone());
    if let Some(f) = files
        .iter()
        .find(|f| f.shard.count != count || f.batch_xxh3 != hash)
    {
        bail!(
            "{}: {} and {} come from different batches (other dumps or another shard count): remove the stale one",
            out_dir.display(),
            first.file_name(),
            f.file_name()
        );
    }
    let missing: Vec<String> = (0..count)
        .filter(|&i| !files.iter().any(|f| f.shard.index == i))
        .map(|i| format!("{i}/{count}"))
        .collect();
    if !missing.is_empty() {
        bail!(
            "{}: shard(s) {} have not finished",
            out_dir.display(),
            missing.join(", ")
        );
    }
    let entries: Vec<Entry> = files.into_iter().flat_map(|f| f.entries).collect();
    // The summaries replace only files of ours.
    guard::check_ours(out_dir)?;
    let path = summary::write(out_dir, &entries)?;
    Ok(Outcome {
        entries,
        summary: Some(path),
    })
}

/// The largest shard file read (a line or two a dump).
const SHARD_FILE_LIMIT: u64 = 1 << 30;

/// What one shard did, for [`merge`].
#[derive(serde::Serialize, serde::Deserialize)]
struct ShardFile {
    shard: Shard,
    /// XXH3-64 of every job's name and dump path, so that shards of
    /// different batches are not merged.
    batch_xxh3: String,
    entries: Vec<Entry>,
}

impl ShardFile {
    fn file_name(&self) -> String {
        format!(
            "batch-shard-{}-of-{}.json",
            self.shard.index, self.shard.count
        )
    }
}

fn batch_hash(all: &[Job]) -> String {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    for j in all {
        h.update(j.name.as_bytes());
        h.update(&[0]);
        h.update(j.dump.to_string_lossy().as_bytes());
        h.update(&[0]);
    }
    format!("{:016x}", h.digest())
}

/// Progress of one dump's filter inside the batch's bar: its replay's
/// samples count; its own length, its later stages (the images) and its
/// end do not.
struct Within<'a> {
    batch: &'a dyn Progress,
    replaying: AtomicBool,
    /// The samples passed on to the batch's bar.
    counted: AtomicU64,
}

impl<'a> Within<'a> {
    fn new(batch: &'a dyn Progress) -> Within<'a> {
        Within {
            batch,
            replaying: AtomicBool::new(true),
            counted: AtomicU64::new(0),
        }
    }

    fn counted(&self) -> u64 {
        self.counted.load(Relaxed)
    }
}

impl Progress for Within<'_> {
    fn inc(&self, n: u64) {
        if self.replaying.load(Relaxed) {
            self.counted.fetch_add(n, Relaxed);
            self.batch.inc(n);
        }
    }
    fn stage(&self, _what: &str, _len: u64) {
        self.replaying.store(false, Relaxed);
    }
}

fn run_job(
    job: &Job,
    opts: &BatchOptions,
    protect: &Arc<guard::Inputs>,
    progress: &dyn Progress,
) -> Entry {
    let mut f = FilterOptions::new(&job.dump, opts.out_dir.join(&job.name));
    f.protect = Arc::clone(protect);
    f.config = job.config;
    f.threads = opts.threads;
    f.html = opts.html;
    f.sigma_map = opts.sigma_map;
    let mut problem = None;
    if let Some(r) = &job.reference {
        // A reference that is not there costs the metrics, not the dump.
        let frames = DumpReader::open(&job.dump).map_or(1, |d| d.header().frames as usize);
        match exr::reference_files(r, frames)
            .iter()
            .find(|p| !p.is_file())
        {
            None => f.reference = Some(r.clone()),
            Some(p) => problem = Some(format!("no metrics: no reference {}", p.display())),
        }
    }
    let entry = |status, problem| Entry {
        name: job.name.clone(),
        dump: job.dump.display().to_string(),
        status,
        problem,
    };
    if !opts.force && up_to_date(&f) {
        return entry(Status::Skipped, problem);
    }
    match catch_unwind(AssertUnwindSafe(|| {
        filter::filter_with_progress(&f, progress)
    })) {
        Ok(Ok(_)) => entry(Status::Filtered, problem),
        Ok(Err(e)) => entry(Status::Failed, Some(format!("{e:#}"))),
        Err(_) => entry(
            Status::Failed,
            Some("internal error (a bug: please report it with this dump)".into()),
        ),
    }
}

/// Whether `f.out_dir` holds a complete run of `f`: its report lists
/// outputs that are all there, and was made from the same configuration,
/// dump bytes and reference.
fn up_to_date(f: &FilterOptions) -> bool {
    let Some(report) = ReportDigest::read(&f.out_dir) else {
        return false;
    };
    let p = &report.provenance;
    if p.config_xxh3 != format!("{:016x}", f.config_hash())
        || !report.outputs.iter().all(|o| f.out_dir.join(o).is_file())
    {
        return false;
    }
    let Ok(dump) = DumpReader::open(&f.dump) else {
        return false;
    };
    if p.dump_xxh3 != format!("{:016x}", dump.content_hash()) {
        return false;
    }
    let h = dump.header();
    let reference = f.reference.as_ref().map(|r| {
        exr::read_reference(r, h.width as usize, h.height as usize, h.frames as usize)
            .map(|img| format!("{:016x}", img.content_hash()))
    });
    match (reference, &p.reference_xxh3) {
        (None, None) => true,
        (Some(Ok(now)), Some(then)) => &now == then,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU64;

    /// The batch's bar: the samples it was given.
    #[derive(Default)]
    struct Bar(AtomicU64);

    impl Progress for Bar {
        fn inc(&self, n: u64) {
            self.0.fetch_add(n, Relaxed);
        }
    }

    /// A dump's replay counts on the batch's bar and in `counted` (what a
    /// failed dump's remainder is taken from); its images' stage does not.
    #[test]
    fn within_counts_the_replay_only() {
        let bar = Bar::default();
        let within = Within::new(&bar);
        within.set_length(999);
        within.inc(40);
        within.inc(60);
        within.stage("images", 3);
        within.inc(1);
        within.finish();
        assert_eq!(bar.0.load(Relaxed), 100);
        assert_eq!(within.counted(), 100);
    }
}
