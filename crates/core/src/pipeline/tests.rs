//! The run's own tests: which images are made beside the replay, and
//! what a run tells its progress.

use super::*;
use crate::synth::SynthParams;

/// A run makes some images beside the replay, from a core whose
/// filtered image is the mean and before the white is known:
/// [`Method::needs_decisions`] must name every image that reads a
/// decision, and [`Method::needs_white`] every one that reads the
/// white (which would panic there). Each image of `run` is the one made
/// after the replay from the true core, for any thread count, and the
/// images said to need decisions do differ.
#[test]
fn the_images_made_beside_the_replay_need_no_decision() {
    let synth = SynthParams {
        width: 24,
        height: 16,
        spp: 16,
        firefly_fraction: 0.02,
        ..SynthParams::default()
    };
    let (records, h): (Vec<Record>, Header) = (synth.records().collect(), synth.header());
    let config = FilterConfig {
        methods: Method::ALL.into_iter().filter(|m| m.available()).collect(),
        ..FilterConfig::DEFAULT
    };
    let white = resolve_white(&config, &records, &h).unwrap();
    let result = replay(
        &records,
        &h,
        &config,
        white,
        ExactSigma::None,
        &crate::progress::Silent,
    );
    assert!(result.counts.rejected > 0);
    let accepted = |i: usize| Decision::accepted(result.decisions[i]);
    let decided = reconstruct(&records, &h, &config, accepted, 0.0);
    let undecided = reconstruct(&records, &h, &config, |_| true, 0.0);
    let shared = Shared::new(&records, &h);
    let truth =
        Estimators::new(&shared, &config, white, &decided).with_decisions(&result.decisions);
    // Every sample accepted, as before the replay.
    let all = vec![Decision::AcceptedStreaming as u8; records.len()];
    let blind = Estimators::new(&shared, &config, white, &undecided).with_decisions(&all);
    for threads in [1, 2] {
        let options = RunOptions {
            threads,
            exact_sigma: ExactSigma::None,
            reference: None,
            progress: &crate::progress::Silent,
            aux: None,
        };
        let run = run(&records, &h, &config, &options).unwrap();
        let made: Vec<(Method, bool)> = run.images.iter().map(|e| (e.method, e.denoised)).collect();
        assert_eq!(made, images_of(&config));
        for e in run.images.iter().filter(|e| !e.method.needs_oidn()) {
            let want = truth.image(e.method).unwrap().0;
            assert!(e.image.data == want.data, "{} differs", e.method);
            let without = blind.image(e.method).unwrap().0;
            assert_eq!(
                e.method.needs_decisions(),
                without.data != want.data,
                "{}",
                e.method
            );
        }
    }
}

/// What a run tells its progress: the replay's samples, then a stage
/// of the images made after it and their metrics, one step each
/// (the images made beside the replay are not counted twice), then
/// the end.
#[test]
fn progress_counts_the_samples_then_the_later_images() {
    use std::sync::Mutex;
    #[derive(Default)]
    struct Log(Mutex<Vec<String>>);
    impl Progress for Log {
        fn inc(&self, n: u64) {
            self.0.lock().unwrap().push(format!("inc {n}"));
        }
        fn stage(&self, what: &str, len: u64) {
            self.0.lock().unwrap().push(format!("stage {what} {len}"));
        }
        fn finish(&self) {
            self.0.lock().unwrap().push("finish".into());
        }
    }
    let synth = SynthParams {
        width: 16,
        height: 12,
        spp: 8,
        ..SynthParams::default()
    };
    let (records, h): (Vec<Record>, Header) = (synth.records().collect(), synth.header());
    let reference = crate::recon::Image::for_header(&h);
    for reference in [None, Some(&reference)] {
        let log = Log::default();
        let options = RunOptions {
            threads: 2,
            exact_sigma: ExactSigma::None,
            reference,
            progress: &log,
            aux: None,
        };
        let config = FilterConfig::DEFAULT;
        let run = run(&records, &h, &config, &options).unwrap();
        let log = log.0.into_inner().unwrap();
        let stage = log.iter().position(|l| l.starts_with("stage")).unwrap();
        let samples: u64 = log[..stage]
            .iter()
            .map(|l| l.strip_prefix("inc ").unwrap().parse::<u64>().unwrap())
            .sum();
        assert_eq!(samples, records.len() as u64);
        // mean is made beside the replay; filtered, filtered_energy
        // and guided after it.
        let beside = images_of(&config)
            .iter()
            .filter(|(m, _)| !m.needs_white() && !m.needs_decisions())
            .count();
        let later = run.images.len() - beside + reference.is_some() as usize;
        assert!(beside >= 1 && later >= 2);
        assert_eq!(log[stage], format!("stage images {later}"));
        let steps = &log[stage + 1..log.len() - 1];
        assert_eq!(steps, vec!["inc 1".to_string(); later], "{log:?}");
        assert_eq!(log.last().unwrap(), "finish");
    }
}
