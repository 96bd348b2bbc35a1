//! The estimators: how each [`Method`]'s image is made from a dump, the
//! filter's decisions and a configuration (what each method is, needs
//! and shares is its row of [`crate::method::TABLE`]). `filter`, `sweep`, the
//! equal-time comparison and the regression fixtures all ask it.
//!
//! Estimators that share work (the per-pixel grouping behind median,
//! trimmed, mon and gmon; one pass for median and trimmed, one for mon and
//! gmon; filtered_energy; the confidence intervals; OIDN of the mean)
//! compute it once: on first use, or all of it up front with
//! [`Estimators::prepare`] before the images are made in parallel
//! ([`Piece::of`] says which method uses which piece). Each
//! image's time includes the work it shares with others, so it is the
//! cost of that image alone.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use crate::config::FilterConfig;
use crate::density::Decision;
use crate::dump::{Header, Record};
use crate::imagespace::{self, oidn::OidnError};
use crate::method::Method;
pub use crate::method::Piece;
use crate::par::prelude::*;
use crate::recon::confidence::{self, Interval};
use crate::recon::groups::PixelGroups;
use crate::recon::mon::{self, MonImages};
use crate::recon::robust::{self, RobustImages};
use crate::recon::{Image, Reconstruction, clamp, energy, rwmc, statmc};

mod guided;

/// The mean and filtered images and what the image-space methods need.
pub struct Core {
    pub reconstruction: Reconstruction,
    /// `mean − filtered` ([`energy::removed`]).
    pub removed: Image,
    /// Seconds of the passes that made mean and filtered.
    pub reconstruct_seconds: f64,
    /// Seconds of the replay that decided which samples are accepted.
    pub replay_seconds: f64,
}

impl Core {
    pub fn new(
        reconstruction: Reconstruction,
        reconstruct_seconds: f64,
        replay_seconds: f64,
    ) -> Core {
        let (mean, filtered) = (&reconstruction.mean, &reconstruction.filtered);
        // Nothing removed where every sample is accepted: zeros the
        // allocator leaves untouched.
        let removed = if Arc::ptr_eq(mean, filtered) {
            Image::new(mean.width, mean.height, mean.frames)
        } else {
            energy::removed(mean, filtered)
        };
        Core {
            reconstruction,
            removed,
            reconstruct_seconds,
            replay_seconds,
        }
    }
}

/// The mean OIDN denoised, its image and OIDN's seconds ([`Shared`]).
type OidnOfMean = (Arc<Image>, Arc<Image>, f64);

/// Work several estimators share, independent of the configuration.
pub struct Shared<'a> {
    records: &'a [Record],
    header: &'a Header,
    groups: OnceLock<(PixelGroups<'a>, f64)>,
    /// Every pixel's confidence interval (the `_ci` methods).
    interval: OnceLock<(Interval, f64)>,
    /// OIDN's image of the mean and the seconds OIDN took: `oidn` (made
    /// beside the replay) and `guided_oidn` (after it) start from the
    /// same one. Unlike the rest, it reads an [`Estimators`]' core: every
    /// Estimators over one Shared must hold the same mean (the run's
    /// cores share its `Arc`; the mean is kept beside the image to check).
    oidn_mean: OnceLock<Result<OidnOfMean, OidnError>>,
    /// Channels OIDN's input had non-finite, and negative, set to 0, over
    /// every image denoised.
    oidn_zeroed: [AtomicU64; 2],
}

impl<'a> Shared<'a> {
    pub fn new(records: &'a [Record], header: &'a Header) -> Shared<'a> {
        Shared {
            records,
            header,
            groups: OnceLock::new(),
            interval: OnceLock::new(),
            oidn_mean: OnceLock::new(),
            oidn_zeroed: Default::default(),
        }
    }

    /// (non-finite, negative) channels set to 0 in OIDN's inputs so far.
    pub fn oidn_zeroed(&self) -> (u64, u64) {
        let [a, b] = &self.oidn_zeroed;
        (a.load(Relaxed), b.load(Relaxed))
    }

    fn groups(&self) -> &(PixelGroups<'a>, f64) {
        self.groups
            .get_or_init(|| timed(|| PixelGroups::new(self.records, self.header)))
    }

    /// Makes now the shared work of `images` (as `images_of` lists them)
    /// that reads only the samples: the confidence intervals. The pipeline
    /// makes it beside the replay for the images that follow it.
    pub fn prepare(&self, images: &[(Method, bool)]) {
        if images
            .iter()
            .any(|(m, _)| Piece::of(*m).contains(&Piece::Interval))
        {
            self.interval();
        }
    }

    /// Every pixel's confidence interval, made once.
    fn interval(&self) -> &(Interval, f64) {
        self.interval.get_or_init(|| {
            timed(|| confidence::interval(self.records, self.header, confidence::Z))
        })
    }
}

/// The estimators of one configuration over one dump.
pub struct Estimators<'s, 'a> {
    shared: &'s Shared<'a>,
    config: &'s FilterConfig,
    /// The resolved white luminance (the bilateral filter's ΔE uses it);
    /// None before it is known, when no image may need it.
    white: Option<f64>,
    core: &'s Core,
    robust: OnceLock<(RobustImages, f64)>,
    mon: OnceLock<(MonImages, f64)>,
    filtered_energy: OnceLock<(Arc<Image>, f64)>,
    /// The filter's decisions, one byte per record ([`Self::with_decisions`]).
    decisions: Option<&'s [u8]>,
    /// Every pixel's confidence interval of its accepted samples.
    accepted_interval: OnceLock<(Interval, f64)>,
    statmc: OnceLock<(Arc<Image>, f64)>,
    /// The renderer's albedo and normal ([`Self::with_aux`]): OIDN's
    /// auxiliary images and statmc's guide.
    aux: Option<&'s imagespace::oidn::Aux>,
}

impl<'s, 'a> Estimators<'s, 'a> {
    pub fn new(
        shared: &'s Shared<'a>,
        config: &'s FilterConfig,
        white: f64,
        core: &'s Core,
    ) -> Estimators<'s, 'a> {
        Estimators {
            white: Some(white),
            ..Estimators::before_white(shared, config, core)
        }
    }

    /// Estimators for the images that need no white luminance
    /// ([`Method::needs_white`]), made while it is still being resolved.
    pub fn before_white(
        shared: &'s Shared<'a>,
        config: &'s FilterConfig,
        core: &'s Core,
    ) -> Estimators<'s, 'a> {
        Estimators {
            shared,
            config,
            white: None,
            core,
            robust: OnceLock::new(),
            mon: OnceLock::new(),
            filtered_energy: OnceLock::new(),
            decisions: None,
            accepted_interval: OnceLock::new(),
            statmc: OnceLock::new(),
            aux: None,
        }
    }

    /// The same estimators with the renderer's albedo and normal.
    pub fn with_aux(self, aux: Option<&'s imagespace::oidn::Aux>) -> Estimators<'s, 'a> {
        Estimators { aux, ..self }
    }

    /// The same estimators with the filter's decisions (one byte per
    /// record), which the guided images read sample by sample.
    pub fn with_decisions(self, decisions: &'s [u8]) -> Estimators<'s, 'a> {
        Estimators {
            decisions: Some(decisions),
            ..self
        }
    }

    /// Computes now the shared work `images` (as `images_of` lists them)
    /// need ([`Piece::of`]): the per-pixel groups first, then the pieces
    /// made from them and the others side by side. Call it before making
    /// the images in parallel: a thread that waits inside a piece's own
    /// parallel loop may take up any job queued beside it, and one that
    /// asks for the piece being made would wait on itself. Here every
    /// piece is made by one job only, and the groups before any job that
    /// reads them.
    pub fn prepare(&self, images: &[(Method, bool)]) {
        let wanted = |piece: Piece| images.iter().any(|(m, _)| Piece::of(*m).contains(&piece));
        if wanted(Piece::Robust) || wanted(Piece::Mon) {
            self.shared.groups();
        }
        // The accepted samples' intervals and statmc read the same
        // moments: one pass over the dump makes both.
        let together = wanted(Piece::AcceptedInterval) && wanted(Piece::Statmc);
        // One piece a job: rayon would otherwise cut these few items into
        // one run a thread, and two long pieces would follow each other on
        // one thread while the other idled.
        Piece::ALL
            .par_iter()
            .with_max_len(1)
            .filter(|&&piece| wanted(piece))
            .for_each(|piece| match piece {
                Piece::AcceptedInterval if together => {}
                Piece::Statmc if together => self.accepted_interval_and_statmc(),
                Piece::Robust => {
                    self.robust_images();
                }
                Piece::Mon => {
                    self.mon_images();
                }
                Piece::FilteredEnergy => {
                    self.filtered_energy();
                }
                Piece::Interval => {
                    self.shared.interval();
                }
                Piece::OidnMean => {
                    // An error stays in its cell, for the image that needs it.
                    let _ = self.oidn_mean();
                }
                Piece::AcceptedInterval => {
                    self.accepted_interval();
                }
                Piece::Statmc => {
                    self.statmc();
                }
            });
    }

    /// `method`'s image and the seconds it took from the dump. Only OIDN
    /// can fail (its library reports an error). An image that is also
    /// shared work (the mean, filtered, median, …) is shared, not copied.
    pub fn image(&self, method: Method) -> Result<(Arc<Image>, f64), OidnError> {
        let (records, h, c) = (self.shared.records, self.shared.header, self.config);
        let rec = &self.core.reconstruction;
        let mean_s = self.core.reconstruct_seconds;
        let filtered_s = self.core.replay_seconds + mean_s;
        let after = |base: f64, (img, s): (Image, f64)| (Arc::new(img), base + s);
        let made = |(img, s): (Image, f64)| (Arc::new(img), s);
        Ok(match method {
            Method::Mean => (Arc::clone(&rec.mean), mean_s),
            Method::Filtered => (Arc::clone(&rec.filtered), filtered_s),
            Method::Median => self.robust(|r| &r.median),
            Method::Trimmed => self.robust(|r| &r.trimmed),
            Method::Mon => self.mon(|m| &m.mon),
            Method::Gmon => self.mon(|m| &m.gmon),
            Method::Bilateral => after(
                mean_s,
                timed(|| {
                    imagespace::bilateral(&rec.mean, &rec.occupancy, c.bilateral(), self.white())
                }),
            ),
            Method::Median3 => after(
                mean_s,
                timed(|| imagespace::median3(&rec.mean, &rec.occupancy)),
            ),
            Method::FilteredBilateral => after(
                filtered_s,
                timed(|| {
                    imagespace::bilateral(
                        &rec.filtered,
                        &rec.occupancy,
                        c.bilateral(),
                        self.white(),
                    )
                }),
            ),
            Method::Rwmc => made(timed(|| rwmc::rwmc(records, h, &c.rwmc()))),
            Method::Clamp => made(timed(|| {
                clamp::clamped_mean(records, h, c.recon.filter(), c.clamp, &rec.occupancy)
            })),
            Method::FilteredEnergy => {
                let (fe, s) = self.filtered_energy();
                (Arc::clone(fe), *s)
            }
            Method::FilteredEnergyBilateralCi => {
                let (fe, fe_s) = self.filtered_energy();
                let (smoothed, t) = timed(|| {
                    imagespace::bilateral(fe, &rec.occupancy, c.bilateral(), self.white())
                });
                made(self.bounded(&smoothed, fe_s + t))
            }
            Method::Statmc => {
                let (img, s) = self.statmc();
                (Arc::clone(img), *s)
            }
            Method::Guided => self.guided_image(),
            Method::Oidn => self.oidn_mean()?,
            Method::OidnCi => {
                let (denoised, s) = self.oidn_mean()?;
                made(self.bounded(&denoised, s))
            }
            Method::GuidedOidn => self.guided_oidn_image()?,
        })
    }

    /// `img` (made in `seconds`) held inside every pixel's confidence
    /// interval, and the seconds from the dump.
    fn bounded(&self, img: &Image, seconds: f64) -> (Image, f64) {
        let (ci, ci_s) = self.shared.interval();
        let (out, t) = timed(|| ci.bound(img));
        (out, seconds + ci_s + t)
    }

    /// statmc of the accepted samples, made once, and the seconds from the
    /// dump.
    fn statmc(&self) -> &(Arc<Image>, f64) {
        let decisions = self
            .decisions
            .expect("an image that needs the decisions is made with them");
        self.statmc.get_or_init(|| {
            let (img, s) = timed(|| {
                statmc::denoise(
                    self.shared.records,
                    self.shared.header,
                    |i| Decision::accepted(decisions[i]),
                    self.guide(),
                )
            });
            (Arc::new(img), self.core.replay_seconds + s)
        })
    }

    /// The accepted samples' intervals and statmc of them, from one pass
    /// over the dump for both: as [`Self::accepted_interval`] and
    /// [`Self::statmc`] make them, each timed with the pass.
    fn accepted_interval_and_statmc(&self) {
        let decisions = self
            .decisions
            .expect("an image that needs the decisions is made with them");
        let (records, h) = (self.shared.records, self.shared.header);
        let (stats, s) =
            timed(|| statmc::stats_of(records, h, |i| Decision::accepted(decisions[i])));
        let ((interval, ti), (window, tw)) = crate::par::join(
            || timed(|| confidence::from_moments(&stats, h, self.config.guide_z)),
            || timed(|| statmc::Window::new(&stats, h, self.guide())),
        );
        // The statistics are read: gone before the window's longest part.
        drop(stats);
        let (img, t) = timed(|| window.denoise(h));
        drop(window);
        let tw = tw + t;
        let _ = self.accepted_interval.set((interval, s + ti));
        let seconds = self.core.replay_seconds + s + tw;
        let _ = self.statmc.set((Arc::new(img), seconds));
    }

    /// statmc's guide: the renderer's albedo and normal, where given.
    fn guide(&self) -> Option<statmc::Guide<'s>> {
        self.aux.map(|a| statmc::Guide::new(a.albedo(), a.normal()))
    }

    /// The accepted samples' intervals, made once, and their seconds.
    fn accepted_interval(&self) -> &(Interval, f64) {
        let decisions = self
            .decisions
            .expect("an image that needs the decisions is made with them");
        self.accepted_interval.get_or_init(|| {
            timed(|| {
                confidence::interval_of(
                    self.shared.records,
                    self.shared.header,
                    self.config.guide_z,
                    |i| Decision::accepted(decisions[i]),
                )
            })
        })
    }

    /// OIDN's image of the mean, made once for the run ([`Shared`]), and
    /// the seconds from the dump.
    fn oidn_mean(&self) -> Result<(Arc<Image>, f64), OidnError> {
        let mean = &self.core.reconstruction.mean;
        let made = self.shared.oidn_mean.get_or_init(|| {
            let (d, s) = self.oidn(mean)?;
            Ok((Arc::clone(mean), Arc::new(d), s))
        });
        let (of, denoised, s) = made.as_ref().map_err(Clone::clone)?;
        debug_assert!(Arc::ptr_eq(of, mean), "OIDN's image of another mean");
        Ok((Arc::clone(denoised), self.core.reconstruct_seconds + s))
    }

    /// `method`'s image denoised by OIDN (`METHOD+oidn`), and the seconds
    /// from the dump.
    pub fn denoised(&self, method: Method) -> Result<(Arc<Image>, f64), OidnError> {
        let (img, s) = self.image(method)?;
        let (denoised, t) = self.oidn(&img)?;
        Ok((Arc::new(denoised), s + t))
    }

    fn oidn(&self, img: &Image) -> Result<(Image, f64), OidnError> {
        let occupancy = &self.core.reconstruction.occupancy;
        let (d, s) = timed(|| imagespace::oidn::denoise(img, occupancy, self.aux));
        let d = d?;
        let [non_finite, negative] = &self.shared.oidn_zeroed;
        non_finite.fetch_add(d.non_finite, Relaxed);
        negative.fetch_add(d.negative, Relaxed);
        Ok((d.image, s))
    }

    fn white(&self) -> f64 {
        self.white
            .expect("only an image that needs no white is made before it is known")
    }

    /// filtered_energy, made once (its image and the bilateral's input).
    fn filtered_energy(&self) -> &(Arc<Image>, f64) {
        let rec = &self.core.reconstruction;
        self.filtered_energy.get_or_init(|| {
            let (img, s) = timed(|| {
                energy::energy_aware(
                    &rec.filtered,
                    &self.core.removed,
                    &rec.occupancy,
                    self.config.energy_sigma,
                )
            });
            (
                Arc::new(img),
                self.core.replay_seconds + self.core.reconstruct_seconds + s,
            )
        })
    }

    fn robust(&self, pick: impl Fn(&RobustImages) -> &Arc<Image>) -> (Arc<Image>, f64) {
        let (r, s) = self.robust_images();
        (Arc::clone(pick(r)), s)
    }

    /// Median and trimmed, made once, and the seconds from the dump.
    fn robust_images(&self) -> (&RobustImages, f64) {
        let (groups, group_s) = self.shared.groups();
        let (r, s) = self.robust.get_or_init(|| {
            timed(|| robust::robust_images(groups, self.shared.header, self.config.alpha))
        });
        (r, group_s + s)
    }

    fn mon(&self, pick: impl Fn(&MonImages) -> &Arc<Image>) -> (Arc<Image>, f64) {
        let (m, s) = self.mon_images();
        (Arc::clone(pick(m)), s)
    }

    /// mon and gmon, made once, and the seconds from the dump.
    fn mon_images(&self) -> (&MonImages, f64) {
        let (groups, group_s) = self.shared.groups();
        let (m, s) = self.mon.get_or_init(|| {
            timed(|| mon::mon_images(groups, self.shared.header, self.config.mon_groups))
        });
        (m, group_s + s)
    }
}

fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let v = f();
    (v, t.elapsed().as_secs_f64())
}

#[cfg(test)]
mod tests;
