//! A deterministic share of a batch for one of N processes (`--shard I/N`),
//! so that a scheduler's array job fans out with no coordination.

/// Shard `index` of `count` (0 ≤ index < count); `0/1` is the whole batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };
    /// The most shards a batch may have: the partition keeps a load each.
    pub const MAX_COUNT: usize = 1 << 20;
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || format!("expected I/N with 0 ≤ I < N (e.g. 0/4), got {s:?}");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if index >= count {
            return Err(bad());
        }
        if count > Shard::MAX_COUNT {
            return Err(format!(
                "{count} shards: at most {} (one a dump is the most that helps)",
                Shard::MAX_COUNT
            ));
        }
        Ok(Shard { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The shard of each job, balanced by size: jobs from largest to smallest
/// (ties by name), each to the shard with the least bytes so far (ties to
/// the lowest index) — the longest-processing-time rule, within 4/3 of the
/// best balance. The same sizes and names give the same partition in
/// every process.
///
/// ```
/// use pathdensity::commands::batch::shard::partition;
/// let jobs = [("a", 10), ("b", 7), ("c", 5), ("d", 4)];
/// assert_eq!(partition(&jobs, 2), vec![0, 1, 1, 0]);
/// ```
pub fn partition(jobs: &[(&str, u64)], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by(|&a, &b| jobs[b].1.cmp(&jobs[a].1).then(jobs[a].0.cmp(jobs[b].0)));
    let mut load = vec![0u64; count.max(1)];
    let mut shard = vec![0; jobs.len()];
    for j in order {
        let least = (0..load.len())
            .min_by_key(|&s| (load[s], s))
            .expect("at least one shard");
        shard[j] = least;
        load[least] += jobs[j].1;
    }
    shard
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_refuses() {
        assert_eq!("1/4".parse(), Ok(Shard { index: 1, count: 4 }));
        for bad in [
            "4/4",
            "1",
            "a/2",
            "0/0",
            "-1/2",
            "0/1000000000000",
            "0/18446744073709551615",
        ] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn every_job_in_one_shard_and_balanced() {
        let names: Vec<String> = (0..50).map(|i| format!("d{i:02}")).collect();
        let jobs: Vec<(&str, u64)> = names
            .iter()
            .enumerate()
            .map(|(i, n)| (n.as_str(), 1 + (i as u64 * 37) % 101))
            .collect();
        let p = partition(&jobs, 3);
        let mut load = [0u64; 3];
        for (j, &s) in p.iter().enumerate() {
            load[s] += jobs[j].1;
        }
        let (lo, hi) = (*load.iter().min().unwrap(), *load.iter().max().unwrap());
        assert!(hi - lo <= 101, "{load:?}");
        // Input order does not change who gets what.
        let mut rev = jobs.clone();
        rev.reverse();
        let q = partition(&rev, 3);
        for (j, &s) in q.iter().enumerate() {
            assert_eq!(s, p[jobs.len() - 1 - j]);
        }
    }
}
