//! The guided images (docs/filter.md F10): a denoiser's image steered by
//! the filter's evidence, `guided` over statmc and `guided_oidn` over OIDN,
//! with what is white decided by held-out halves of the samples
//! ([`held_out`]): each image made again from each half alone.

use std::sync::Arc;

use super::{Estimators, timed};
use crate::density::Decision;
use crate::imagespace::{self, oidn::OidnError};
use crate::recon::confidence::{self, Interval, Moments};
use crate::recon::held_out::{Decided, Half, HalfFold, Whites};
use crate::recon::per_pixel::RowBand;
use crate::recon::statmc::Stats;
use crate::recon::{Image, energy, guided, held_out, statmc};

impl Estimators<'_, '_> {
    /// `guided`'s image and the seconds from the dump.
    pub(super) fn guided_image(&self) -> (Arc<Image>, f64) {
        let (denoised, s) = self.statmc();
        let (accepted, accepted_s) = self.accepted_interval();
        let (all, all_s) = self.shared.interval();
        let (removed, occupancy) = (&self.core.removed, &self.core.reconstruction.occupancy);
        let (mut out, t) =
            timed(|| self.guided_statmc(denoised, removed, occupancy, accepted, all));
        let (_, t2) = timed(|| {
            self.held_out(&mut out, Whites::Channels, |decided| {
                Ok::<_, std::convert::Infallible>(self.guided_halves(decided))
            })
        });
        (Arc::new(out), s + accepted_s + all_s + t + t2)
    }

    /// `guided_oidn`'s image and the seconds from the dump.
    pub(super) fn guided_oidn_image(&self) -> Result<(Arc<Image>, f64), OidnError> {
        let (denoised, s) = self.oidn_mean()?;
        let (mut out, s) = self.guided(&denoised, s);
        let halves = |decided: &_| self.guided_oidn_halves(decided);
        let (decided, t) = timed(|| self.held_out(&mut out, Whites::Pixels, halves));
        decided?;
        Ok((Arc::new(out), s + t))
    }

    /// `img` (made in `seconds`) steered by the accepted samples
    /// ([`guided::guide`]), and the seconds from the dump.
    fn guided(&self, img: &Image, seconds: f64) -> (Image, f64) {
        let (accepted, accepted_s) = self.accepted_interval();
        let (all, all_s) = self.shared.interval();
        let white = 1.0 / self.config.exposure;
        let (out, t) = timed(|| guided::guide(img, accepted, all, white));
        (
            out,
            seconds.max(self.core.replay_seconds) + accepted_s + all_s + t,
        )
    }

    /// `g`, a guided image, with its `whites` decided by the held-out
    /// halves ([`held_out`]): `make(decided)` makes the same image from
    /// each half's samples alone, kept with that half's intervals at the
    /// decided pixels. Nothing is made where nothing is white.
    fn held_out<E>(
        &self,
        g: &mut Image,
        whites: Whites,
        make: impl FnOnce(&Decided) -> Result<[Half; 2], E>,
    ) -> Result<(), E> {
        if !self.config.held_out {
            return Ok(());
        }
        let (all, _) = self.shared.interval();
        let white = 1.0 / self.config.exposure;
        let decided = Decided::of(g, all, white, whites);
        if decided.is_empty() {
            return Ok(());
        }
        let [first, second] = make(&decided)?;
        let (accepted, _) = self.accepted_interval();
        let halves = [&first, &second];
        held_out::prefer_mean(g, all, &accepted.count, halves, &decided, white, whites);
        Ok(())
    }

    /// Both halves' intervals at the `decided` pixels, of their samples
    /// and as [`guided::floor`]s of their accepted ones, from one read of
    /// the dump at the pixels `wanted` marks (all where None), band by
    /// band with `halo` rows either side (one at least); `also(band, k,
    /// folds)` is given each band's folds of half k.
    fn halves_at<S: Default + Clone + Send>(
        &self,
        decided: &Decided,
        halo: usize,
        wanted: Option<&[bool]>,
        add: impl Fn(&mut S, [f64; 3]) + Sync,
        accepted_moments: impl Fn(&HalfFold<S>) -> &Moments,
        mut also: impl FnMut(&RowBand, usize, &[&HalfFold<S>]),
    ) -> [HalfAt; 2] {
        let decisions = self
            .decisions
            .expect("an image that needs the decisions is made with them");
        let (records, h) = (self.shared.records, self.shared.header);
        let guide_z = self.config.guide_z;
        let mut at = [(); 2].map(|_| HalfAt {
            all: decided.empty_interval(confidence::Z),
            floors: decided.map(|_| [0.0; 3]),
        });
        let bands = held_out::bands::<S>(h, halo, held_out::BAND_BYTES);
        let accepted = |i| Decision::accepted(decisions[i]);
        held_out::fold_halves(records, h, &bands, wanted, accepted, add, |band, folds| {
            let (bh, (places, pixels)) = (&band.header, decided.in_band(band));
            for (k, at) in at.iter_mut().enumerate() {
                let half = held_out::half_of(folds, k);
                let z = confidence::Z;
                let all = confidence::from_moments_at(&half, |f| &f.all, bh, z, &pixels);
                let a = confidence::from_moments_at(
                    &half,
                    |f| accepted_moments(f),
                    bh,
                    guide_z,
                    &pixels,
                );
                at.all.put_at(places.clone(), &all);
                let floors = &mut at.floors.data[places.clone()];
                floors
                    .iter_mut()
                    .enumerate()
                    .for_each(|(i, f)| *f = guided::floor(&a, i));
                also(band, k, &half);
            }
        });
        at
    }

    /// `guided_oidn`'s image made from each half's samples alone, kept
    /// with the half's intervals at the `decided` pixels.
    fn guided_oidn_halves(&self, decided: &Decided) -> Result<[Half; 2], OidnError> {
        // OIDN, the run's peak, needs only each half's means and counts
        // over the film; its intervals are made at the decided pixels.
        let h = self.shared.header;
        let mut mean = [Image::for_header(h), Image::for_header(h)];
        let mut count = [(); 2].map(|_| vec![0; h.pixels() * h.frames as usize]);
        let film = |band: &RowBand, k: usize, folds: &[&HalfFold<Moments>]| {
            let own = band.own.clone();
            let (mean, count) = (band.own_of(&mut mean[k].data), band.own_of(&mut count[k]));
            for ((m, n), f) in mean.iter_mut().zip(count).zip(&folds[own]) {
                (*m, *n) = (f.all.mean, f.all.n);
            }
        };
        let [at0, at1] = self.halves_at(decided, 1, None, Moments::add, |f| &f.accepted, film);
        let ([mean0, mean1], [count0, count1]) = (mean, count);
        // Each half's film goes once OIDN has denoised it.
        let half = |mean: Image, count: Vec<u32>, at: HalfAt| -> Result<Half, OidnError> {
            let d = imagespace::oidn::denoise(&mean, &count, self.aux)?;
            drop((mean, count));
            Ok(self.steered_half(&decided.image(&d.image), &at))
        };
        Ok([half(mean0, count0, at0)?, half(mean1, count1, at1)?])
    }

    /// A half's `denoised` image at the decided pixels, in their order,
    /// steered by its intervals there ([`guided::guide_from`]).
    fn steered_half(&self, denoised: &Image, at: &HalfAt) -> Half {
        let white = 1.0 / self.config.exposure;
        let g = guided::guide_from(denoised, |i| at.floors.data[i], &at.all, white);
        Half::new(&g, &at.all)
    }

    /// `guided`'s image of statmc's `denoised`: the energy the filter
    /// `removed` spread back as in filtered_energy, steered by the
    /// intervals ([`guided::guide`]), and held by blocks, which statmc,
    /// unlike OIDN, needs (docs/filter.md F10).
    fn guided_statmc(
        &self,
        denoised: &Image,
        removed: &Image,
        occupancy: &[u32],
        accepted: &Interval,
        all: &Interval,
    ) -> Image {
        let with_energy =
            energy::energy_aware(denoised, removed, occupancy, self.config.energy_sigma);
        self.guided_statmc_of(with_energy, accepted, all)
    }

    /// [`Self::guided_statmc`] of statmc's image with the removed energy
    /// spread back.
    fn guided_statmc_of(&self, with_energy: Image, accepted: &Interval, all: &Interval) -> Image {
        let white = 1.0 / self.config.exposure;
        let mut g = guided::guide(&with_energy, accepted, all, white);
        drop(with_energy);
        all.hold_blocks(&mut g, confidence::Z);
        g
    }

    /// `guided`'s image made from each half's samples alone at the
    /// `decided` pixels, kept with the half's intervals there: statmc of
    /// the half's accepted samples steered by those intervals
    /// ([`guided::guide`]). The removed energy's spread and the blocks,
    /// which read far across the film, are left out: at the pixels decided
    /// they moved the decision by little (docs/RESULTS.md, "The guided
    /// image"), and without them only the pixels statmc's window reads
    /// there are folded, and the window made there alone.
    fn guided_halves(&self, decided: &Decided) -> [Half; 2] {
        let h = self.shared.header;
        let wanted = decided.around(h, statmc::HALO);
        let wanted = (!wanted.iter().all(|&w| w)).then_some(&wanted[..]);
        let guide = self.guide();
        let mut denoised = [(); 2].map(|_| vec![[0.0; 3]; decided.len()]);
        let window = |band: &RowBand, k: usize, folds: &[&HalfFold<Stats>]| {
            let g = guide.map(|g| g.of(band.pixels.clone()));
            decided.window_at(band, folds, g, &mut denoised[k]);
        };
        let add = statmc::stats_adder();
        let at = self.halves_at(
            decided,
            statmc::HALO,
            wanted,
            add,
            |f| f.accepted.as_ref(),
            window,
        );
        let row = |data: Vec<[f64; 3]>| Image {
            width: data.len(),
            height: 1,
            frames: 1,
            data,
        };
        let ([d0, d1], [at0, at1]) = (denoised, at);
        [(d0, at0), (d1, at1)].map(|(d, at)| self.steered_half(&row(d), &at))
    }
}

/// One half's intervals at the decided pixels, in their order: of all
/// its samples, and the [`guided::floor`]s of its accepted ones.
struct HalfAt {
    all: Interval,
    floors: Image,
}

#[cfg(test)]
mod tests {
    use crate::config::FilterConfig;
    use crate::density::ExactSigma;
    use crate::dump::{Header, Order, Record};
    use crate::method::Method;
    use crate::pipeline::{self, RunOptions};
    use crate::progress::Silent;
    use crate::recon::{held_out, statmc};
    use crate::synth::SynthParams;

    /// A pass-major film whose halves are folded in bands of rows (a few
    /// rows each in this crate's tests) makes `guided` with the same bits
    /// as the same records in no declared order, whose halves are folded
    /// whole: the bands' halos, their own rows and statmc's window on each
    /// are the film's. A light makes white pixels, fireflies rejected
    /// samples. So does a record out of its place in a late band, after
    /// which the halves fold the film whole, some bands already given.
    #[test]
    fn banded_halves_make_the_films_image() {
        let synth = SynthParams {
            width: 24,
            height: 40,
            spp: 16,
            order: Order::PassMajor,
            firefly_fraction: 0.02,
            light: Some((5, 12, 6, 40.0)),
            ..SynthParams::default()
        };
        let (h, records): (Header, Vec<Record>) = (synth.header(), synth.records().collect());
        let bands = held_out::bands::<statmc::Stats>(&h, statmc::HALO, held_out::BAND_BYTES);
        assert!(bands.len() > 10);
        let image = |records: &[Record], h: &Header| {
            let options = RunOptions {
                threads: 2,
                exact_sigma: ExactSigma::None,
                reference: None,
                progress: &Silent,
                aux: None,
            };
            let run = pipeline::run(records, h, &FilterConfig::DEFAULT, &options).unwrap();
            let img = run.image(Method::Guided).unwrap();
            let bits: Vec<u64> = img.data.iter().flatten().map(|v| v.to_bits()).collect();
            bits
        };
        let scan = Header {
            order: Order::Unspecified,
            ..h.clone()
        };
        assert_eq!(image(&records, &h), image(&records, &scan));
        // Pass 2's sample of pixel (3, 35) lies in the light's pixel
        // (5, 12), whose band was given before the one that finds it:
        // what that band made is made again from the film.
        let mut misplaced = records.clone();
        misplaced[2 * 24 * 40 + 35 * 24 + 3].x = 5.5;
        misplaced[2 * 24 * 40 + 35 * 24 + 3].y = 12.5;
        let moved = image(&misplaced, &h);
        assert_ne!(moved, image(&records, &h));
        assert_eq!(moved, image(&misplaced, &scan));
    }
}
