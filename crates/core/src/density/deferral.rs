//! The share of searches the in-order pass takes over from the parallel
//! search. It balances the two sides of a batch; no decision depends on it.

/// How many searches the in-order pass takes over from the parallel one.
///
/// A sample searched in parallel against the lagging T mostly needs a
/// recheck in order as well (most do at large k; docs/BENCHMARKS.md,
/// "The replay's constants").
/// Searching it in order instead, against the current T, costs
/// the in-order pass a little more than the recheck would but saves the
/// parallel search altogether. With one thread that is pure gain; with
/// more, the in-order pass must not become the bottleneck, so the share
/// follows the timings: up while the in-order pass finishes first, down
/// while it is the one waited for and has deferred searches to hand back.
/// Only the timings depend on the share.
pub(super) struct Deferral {
    pub(super) share: f64,
    pub(super) fixed: bool,
}

impl Deferral {
    pub(super) fn new(fixed: Option<f64>) -> Deferral {
        match fixed {
            Some(s) => Deferral {
                share: s.clamp(0.0, 1.0),
                fixed: true,
            },
            None if crate::par::current_num_threads() == 1 => Deferral {
                share: 1.0,
                fixed: true,
            },
            None => Deferral {
                share: 0.5,
                fixed: false,
            },
        }
    }

    /// Adjusts the share after a batch whose in-order pass took
    /// `in_order` seconds and ran `deferred` deferred searches while the
    /// search of the next batch took `search`. An in-order pass that is
    /// slower without running any deferred search (the first samples of a
    /// region, checked against a T that grows under them) has nothing to
    /// hand back: lowering the share then would only cost the parallel
    /// searches their deferrals once the pass is fast again.
    pub(super) fn update(&mut self, in_order: f64, search: f64, deferred: usize) {
        const STEP: f64 = 1.0 / 32.0;
        if !self.fixed {
            let step = if in_order < search {
                STEP
            } else if deferred > 0 {
                -STEP
            } else {
                0.0
            };
            self.share = (self.share + step).clamp(0.0, 1.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Deferral;

    /// The adaptive share rises while the in-order pass finishes first,
    /// falls while the search waits for it, and stays within [0, 1]; a
    /// fixed share never moves.
    #[test]
    fn deferral_share_follows_the_slower_side() {
        let mut d = Deferral {
            share: 0.5,
            fixed: false,
        };
        d.update(1.0, 2.0, 0);
        assert!(d.share > 0.5);
        for _ in 0..100 {
            d.update(1.0, 2.0, 7);
        }
        assert_eq!(d.share, 1.0);
        // Slower in order but with no deferred search to give back.
        d.update(2.0, 1.0, 0);
        assert_eq!(d.share, 1.0);
        d.update(2.0, 1.0, 7);
        assert!(d.share < 1.0);
        for _ in 0..100 {
            d.update(2.0, 1.0, 7);
        }
        assert_eq!(d.share, 0.0);
        let mut fixed = Deferral::new(Some(0.25));
        fixed.update(2.0, 1.0, 7);
        assert_eq!(fixed.share, 0.25);
    }
}
