//! What a batch filters: dumps named on the command line (paths or glob
//! patterns) or in a manifest, each with its output name, its reference
//! and its configuration (the batch's, with the manifest line's overrides).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

use crate::config::FilterConfig;
use crate::io::guard;

/// One dump to filter into `OUTDIR/name/`.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// The output folder's name: the dump's file stem unless the manifest
    /// names it. Unique within a batch.
    pub name: String,
    pub dump: PathBuf,
    /// The reference to measure against, if one is expected.
    pub reference: Option<PathBuf>,
    pub config: FilterConfig,
}

/// Where the dumps come from and what they share.
pub struct Inputs<'a> {
    /// Paths, or glob patterns (`*`, `?`, `[…]`) expanded in sorted order.
    pub dumps: &'a [String],
    /// A manifest file (see [`parse_manifest`]).
    pub manifest: Option<&'a Path>,
    /// The configuration every dump shares unless its manifest line says
    /// otherwise.
    pub config: &'a FilterConfig,
    /// Where each dump's reference is, `{dir}` and `{stem}` standing for
    /// the dump's folder and file stem (e.g. `{dir}/{stem}_ref.exr`); a
    /// manifest's `--reference` wins.
    pub reference_pattern: Option<&'a str>,
}

/// Every job of `inputs`, in the order given, names checked unique.
pub fn collect(inputs: &Inputs) -> Result<Vec<Job>> {
    let mut jobs = Vec::new();
    for pattern in inputs.dumps {
        for dump in expand(pattern)? {
            jobs.push(Job {
                name: stem(&dump),
                reference: inputs.reference_pattern.map(|p| reference_of(p, &dump)),
                dump,
                config: *inputs.config,
            });
        }
    }
    if let Some(m) = inputs.manifest {
        let text = guard::read_input_text(m, MANIFEST_LIMIT)?;
        let base = m.parent().unwrap_or(Path::new(""));
        for job in parse_manifest(&text, base, inputs.config)
            .map_err(|e| anyhow::anyhow!("{}:{e}", m.display()))?
        {
            let reference = job
                .reference
                .or_else(|| inputs.reference_pattern.map(|p| reference_of(p, &job.dump)));
            jobs.push(Job { reference, ..job });
        }
    }
    if jobs.is_empty() {
        bail!("no dump to filter: name dumps, glob patterns or --manifest FILE");
    }
    let mut seen: BTreeMap<&str, &Path> = BTreeMap::new();
    for j in &jobs {
        if reserved(&j.name) {
            bail!(
                "{}: its output name {:?} is one the batch writes itself (summaries, shard files): rename it, or name it in a manifest (--name)",
                j.dump.display(),
                j.name
            );
        }
        if let Some(first) = seen.insert(&j.name, &j.dump) {
            bail!(
                "{} and {} would both write OUTDIR/{}: rename one, or name them in a manifest (--name)",
                first.display(),
                j.dump.display(),
                j.name
            );
        }
    }
    Ok(jobs)
}

/// The largest manifest read (a line a dump: millions of dumps).
const MANIFEST_LIMIT: u64 = 1 << 28;

/// Names in OUTDIR that the batch writes itself, and names that are not
/// one folder: no dump's output may have them.
fn reserved(name: &str) -> bool {
    let ours = ["summary.csv", "summary.json", "summary.html", guard::MARKER];
    ours.contains(&name)
        || (name.starts_with("batch-shard-") && name.ends_with(".json"))
        || name.is_empty()
        || name.starts_with('.')
        || name.contains(['/', '\\'])
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map_or_else(|| "dump".into(), |s| s.to_string_lossy().into_owned())
}

/// `pattern` with `{dir}` and `{stem}` of `dump` substituted.
fn reference_of(pattern: &str, dump: &Path) -> PathBuf {
    let dir = dump
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    PathBuf::from(
        pattern
            .replace("{dir}", &dir.to_string_lossy())
            .replace("{stem}", &stem(dump)),
    )
}

/// A path as it is, or a glob pattern's matches in sorted order (none is
/// an error: a pattern that matches nothing is a typo, not an empty batch).
fn expand(pattern: &str) -> Result<Vec<PathBuf>> {
    if !pattern.contains(['*', '?', '[']) {
        return Ok(vec![PathBuf::from(pattern)]);
    }
    let mut paths = glob::glob(pattern)
        .map_err(|e| anyhow::anyhow!("{pattern}: not a glob pattern: {e}"))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow::anyhow!("{pattern}: {e}"))?;
    paths.sort();
    if paths.is_empty() {
        bail!("{pattern}: matches no file");
    }
    Ok(paths)
}

/// Parses a manifest: one dump a line, then options as on the command
/// line; blank lines and `#` comments are skipped; relative paths are
/// relative to `base` (the manifest's folder).
///
/// ```text
/// # dump                 options
/// shots/a.pds            --reference refs/a.exr
/// shots/b.pds            --reference refs/b.exr --k 10 --sigma-color 100
/// "shots/c d.pds"        --name c_d --white auto
/// ```
///
/// `--reference PATH` and `--name NAME` are per dump; any other `--FIELD
/// VALUE` overrides that field of `config` (each field of the
/// configuration is its flag, `--sigma-color` is `sigma_color`). Errors
/// are `LINE: problem`.
pub fn parse_manifest(text: &str, base: &Path, config: &FilterConfig) -> Result<Vec<Job>, String> {
    let mut jobs = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let at = |e: String| format!("{}: {e}", i + 1);
        let line = line.split_once('#').map_or(line, |(l, _)| l);
        let words = split_words(line).map_err(at)?;
        let Some((dump, rest)) = words.split_first() else {
            continue;
        };
        if dump.starts_with("--") {
            return Err(at(format!("the line starts with {dump}, not a dump")));
        }
        let dump = base.join(dump);
        let mut name = stem(&dump);
        let mut reference = None;
        let mut overrides = Vec::new();
        for pair in rest.chunks(2) {
            let key = pair[0]
                .strip_prefix("--")
                .ok_or_else(|| at(format!("expected --OPTION VALUE, got {:?}", pair[0])))?;
            let value = pair
                .get(1)
                .ok_or_else(|| at(format!("--{key} needs a value")))?;
            match key {
                "name" => name = value.clone(),
                "reference" => reference = Some(base.join(value)),
                _ => overrides.push((key, value.as_str())),
            }
        }
        if name.is_empty() || name.contains(['/', '\\']) || name.starts_with('.') {
            return Err(at(format!(
                "--name {name:?}: a folder name, not a path or a hidden name"
            )));
        }
        let config = with_overrides(config, &overrides).map_err(at)?;
        jobs.push(Job {
            name,
            dump,
            reference,
            config,
        });
    }
    Ok(jobs)
}

/// `config` with each `(flag, value)` set, through the configuration's
/// JSON form so that every field is an option with no list to keep: a
/// value is read as JSON when it parses (numbers), as a string otherwise
/// (`auto`, `logluv`), and as a comma-separated list for a list field
/// (`methods`).
fn with_overrides(
    config: &FilterConfig,
    overrides: &[(&str, &str)],
) -> Result<FilterConfig, String> {
    let mut json = serde_json::to_value(config).expect("the configuration serialises");
    let fields = json
        .as_object_mut()
        .expect("a struct serialises as an object");
    for &(flag, value) in overrides {
        let slot = fields
            .get_mut(&flag.replace('-', "_"))
            .ok_or_else(|| format!("--{flag} is not an option of the configuration"))?;
        *slot = match slot {
            serde_json::Value::Array(_) => value
                .split(',')
                .map(|v| serde_json::Value::String(v.trim().to_string()))
                .collect(),
            _ => serde_json::from_str(value)
                .unwrap_or_else(|_| serde_json::Value::String(value.to_string())),
        };
    }
    let config: FilterConfig = serde_json::from_value(json).map_err(|e| {
        let flags: Vec<String> = overrides
            .iter()
            .map(|(f, v)| format!("--{f} {v}"))
            .collect();
        format!("{}: {e}", flags.join(" "))
    })?;
    config
        .validate()
        .map_err(|e| format!("--{} {}", e.field.replace('_', "-"), e.problem))?;
    Ok(config)
}

/// Splits on whitespace; double quotes keep spaces in a word.
fn split_words(line: &str) -> Result<Vec<String>, String> {
    let mut words = Vec::new();
    let mut word: Option<String> = None;
    let mut quoted = false;
    for c in line.chars() {
        match c {
            '"' => {
                quoted = !quoted;
                word.get_or_insert_default();
            }
            c if c.is_whitespace() && !quoted => words.extend(word.take()),
            c => word.get_or_insert_default().push(c),
        }
    }
    if quoted {
        return Err("a quote is not closed".into());
    }
    words.extend(word);
    Ok(words)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{ColorSpace, Method, White};

    #[test]
    fn manifest_lines_override_the_shared_configuration() {
        let text = "# a comment\n\n a.pds --reference r/a.exr\n\"b c.pds\" --name bc --k 10 --white auto --color-space cielab --methods median,clamp # why\n";
        let base = FilterConfig::DEFAULT;
        let jobs = parse_manifest(text, Path::new("m"), &base).unwrap();
        assert_eq!(jobs.len(), 2);
        assert_eq!(jobs[0].name, "a");
        assert_eq!(jobs[0].dump, Path::new("m/a.pds"));
        assert_eq!(jobs[0].reference.as_deref(), Some(Path::new("m/r/a.exr")));
        assert_eq!(jobs[0].config, base);
        let b = &jobs[1];
        assert_eq!(
            (b.name.as_str(), b.dump.as_path()),
            ("bc", Path::new("m/b c.pds"))
        );
        assert_eq!(b.config.k, 10);
        assert_eq!(b.config.white, White::Auto);
        assert_eq!(b.config.color_space, ColorSpace::Cielab);
        assert!(b.config.methods.contains(Method::Clamp));
        assert!(!b.config.methods.contains(Method::Trimmed));
        assert_eq!(b.config.sigma_color, base.sigma_color);
    }

    #[test]
    fn bad_manifest_lines_say_which_line_and_why() {
        let base = FilterConfig::DEFAULT;
        let err = |t: &str| parse_manifest(t, Path::new(""), &base).unwrap_err();
        assert!(err("a.pds\nb.pds --kk 3").starts_with("2: --kk is not an option"));
        assert!(err("a.pds --k").contains("--k needs a value"));
        assert!(err("a.pds --k 0").starts_with("1: --k "));
        assert!(err("a.pds --k ten").contains("--k ten"));
        assert!(err("a.pds --name ../x").contains("--name"));
        assert!(err("\"a.pds").contains("quote"));
        assert!(err("--k 3").contains("not a dump"));
    }

    #[test]
    fn reference_patterns_substitute_folder_and_stem() {
        let r = reference_of("{dir}/{stem}_ref.exr", Path::new("shots/a.pds"));
        assert_eq!(r, Path::new("shots/a_ref.exr"));
        assert_eq!(
            reference_of("{dir}/{stem}.exr", Path::new("a.pds")),
            Path::new("./a.exr")
        );
    }
}
