//! `pathdensity regress [DIR] [--bless]`: re-run every fixture and compare
//! with its stored expectations, or rewrite them.

use std::path::Path;

use anyhow::Result;

use crate::regress;

/// What a regression run found: one line per fixture, an indented line per
/// drift.
pub struct Outcome {
    pub text: String,
    pub drifted: usize,
    pub fixtures: usize,
}

/// Checks (or blesses) every fixture under `root`. A fixture that cannot
/// run (or be blessed) counts as drifted, and the others still run.
pub fn regress(root: &Path, bless: bool) -> Result<Outcome> {
    let mut out = String::new();
    let mut failed = 0;
    let fixtures = regress::find(root)?;
    for dir in &fixtures {
        let name = dir.display();
        if bless {
            // Each fixture is blessed whole or left as it was; one that
            // cannot run does not stop the others.
            match regress::bless(dir) {
                Ok(m) => out += &format!("{name}: blessed ({} images)\n", m.expected.images.len()),
                Err(e) => {
                    failed += 1;
                    out += &format!("{name}: NOT BLESSED (left as it was): {e:#}\n");
                }
            }
            continue;
        }
        // A broken fixture is reported and the others still run.
        let drift = match regress::check(dir) {
            Ok(d) => d,
            Err(e) => vec![format!("cannot run: {e:#}")],
        };
        if drift.is_empty() {
            out += &format!("{name}: ok\n");
        } else {
            failed += 1;
            out += &format!("{name}: DRIFT\n");
            for d in drift {
                out += &format!("  {d}\n");
            }
        }
    }
    Ok(Outcome {
        text: out,
        drifted: failed,
        fixtures: fixtures.len(),
    })
}
