//! F6a through a grid over every valid sample: each stored sample searched
//! in it, cells sized to the density of the samples.

use crate::density::index::NeighbourIndex;
use crate::density::index::grid::Grid;
use crate::density::sigma::KBest;
use crate::density::{ExactSigma, FilterResult};
use crate::dump::{Header, Record, Validity};
use crate::joint::JointSpace;
use crate::par::prelude::*;

/// Samples a cell of the grid over every sample holds on average, at most:
/// that grid is far denser than T's, whose one-unit cells would hold
/// hundreds of samples at 64 spp and make every search scan them
/// (docs/BENCHMARKS.md, "The default run").
const SAMPLES_PER_CELL: f64 = 64.0;

/// The log2 of the cell side (joint units) that keeps `valid` samples over
/// `extent`'s first `axes` axes within [`SAMPLES_PER_CELL`] a cell.
fn cell_side(extent: [f64; 3], axes: usize, valid: u64) -> i32 {
    let volume: f64 = extent[..axes].iter().product();
    let mut log2 = 0;
    while log2 > -8 && valid as f64 / volume * 2f64.powi(log2 * axes as i32) > SAMPLES_PER_CELL {
        log2 -= 1;
    }
    log2
}

pub(super) fn against_all<const D: usize>(
    records: &[Record],
    header: &Header,
    space: &JointSpace,
    k: usize,
    exact: ExactSigma,
    result: &mut FilterResult,
) {
    let extent = space.extent(header);
    let side = cell_side(extent, D - 3, result.counts.valid);
    // Built whole, in parallel, each cell's points in one array and no
    // second copy of them (about 24 bytes a sample): the cells are counted
    // from the image coordinates alone, then the joint-space points (the
    // colour transform is most of the build's cost) are placed.
    let valid = |r: &Record| r.validity(header) == Validity::Valid;
    let (index, stored) = Grid::<D>::packed(
        extent,
        side,
        records,
        |r| valid(r).then(|| space.image_point::<D>(r)),
        |r| valid(r).then(|| space.point::<D>(r)),
        // The stored samples to search, with their ids.
        |i| super::stored(result, i) && super::needs_search(result, exact, i),
    );
    let verdicts: Vec<_> = stored
        .par_iter()
        .map_init(
            || (KBest::new(k), Default::default()),
            |(kb, scratch), &(i, id)| {
                let q = space.point::<D>(&records[i]);
                index
                    .search(&q, Some(id), exact.goal(i), kb, scratch)
                    .verdict
            },
        )
        .collect();
    for (&(i, _), v) in stored.iter().zip(&verdicts) {
        super::record(result, exact, i, v.accepted(), v.sigma());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_shrink_with_the_density_of_samples() {
        // 128 × 128 pixels at σ_image = 3: 42.7 joint units a side.
        let extent = [128.0 / 3.0, 128.0 / 3.0, 1.0];
        let pixels = 128 * 128;
        assert_eq!(cell_side(extent, 2, pixels * 4), 0);
        // 16 spp: 144 samples a unit², 36 in a cell of ½.
        assert_eq!(cell_side(extent, 2, pixels * 16), -1);
        assert_eq!(cell_side(extent, 2, pixels * 64), -2);
        assert_eq!(cell_side(extent, 2, u64::MAX), -8);
    }
}
