//! Data parallelism: rayon with the `parallel` feature (the default), else
//! a sequential stand-in with the same interface. Every parallel loop in
//! this crate writes each result to its own index and the replay's
//! schedule cannot change a decision, so both give the same bytes
//! (`tests/sequential.rs` checks it).

#[cfg(feature = "parallel")]
pub use rayon::{
    ThreadPool, ThreadPoolBuildError, current_num_threads, current_thread_index, join,
};

/// The iterator traits (`par_iter`, `par_chunks_mut`, `into_par_iter`,
/// `map_init`, …).
#[cfg(feature = "parallel")]
pub mod prelude {
    pub use rayon::prelude::*;
}

/// Waits for `flag`, set by the other closure of a [`join`], without
/// parking the thread: runs pending pool jobs, else yields the core.
/// rayon parks a thread after some idle rounds, and a parked thread wakes
/// late (docs/BENCHMARKS.md, "The replay's constants").
#[cfg(feature = "parallel")]
pub fn wait_for(flag: &std::sync::atomic::AtomicBool) {
    use std::sync::atomic::Ordering::Acquire;
    while !flag.load(Acquire) {
        if rayon::yield_now() != Some(rayon::Yield::Executed) {
            std::thread::yield_now();
        }
    }
}

/// The most worker threads a pool is given: more than the cores only
/// cost (the results are the same for any count), and thousands exhaust
/// the process table. Four a core, and never fewer than 64.
pub fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (4 * cores).max(64)
}

/// A pool of `threads` workers (0: one per core, at most [`max_threads`]).
/// Without the `parallel` feature, the one thread there is.
pub fn pool(threads: usize) -> Result<ThreadPool, ThreadPoolBuildError> {
    #[cfg(feature = "parallel")]
    return rayon::ThreadPoolBuilder::new()
        .num_threads(threads.min(max_threads()))
        .build();
    #[cfg(not(feature = "parallel"))]
    {
        let _ = threads;
        Ok(ThreadPool)
    }
}

#[cfg(not(feature = "parallel"))]
pub use sequential::*;

#[cfg(not(feature = "parallel"))]
mod sequential {
    /// Runs `a`, then `b`.
    pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
    where
        A: FnOnce() -> RA,
        B: FnOnce() -> RB,
    {
        let ra = a();
        (ra, b())
    }

    pub fn current_num_threads() -> usize {
        1
    }

    pub fn current_thread_index() -> Option<usize> {
        Some(0)
    }

    /// The two closures of a sequential [`join`] run one after the other,
    /// so nothing is left to wait for.
    pub fn wait_for(_flag: &std::sync::atomic::AtomicBool) {}

    /// The one thread there is.
    pub struct ThreadPool;

    impl ThreadPool {
        pub fn install<R>(&self, f: impl FnOnce() -> R) -> R {
            f()
        }
        pub fn current_num_threads(&self) -> usize {
            1
        }
    }

    /// Never happens without threads.
    #[derive(Debug)]
    pub struct ThreadPoolBuildError;

    impl std::fmt::Display for ThreadPoolBuildError {
        fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("no thread pool")
        }
    }

    impl std::error::Error for ThreadPoolBuildError {}

    /// Sequential versions of the rayon iterator methods this crate uses.
    pub mod prelude {
        pub trait ParallelSlice<T> {
            fn par_iter(&self) -> std::slice::Iter<'_, T>;
            fn par_chunks(&self, n: usize) -> std::slice::Chunks<'_, T>;
        }

        impl<T> ParallelSlice<T> for [T] {
            fn par_iter(&self) -> std::slice::Iter<'_, T> {
                self.iter()
            }
            fn par_chunks(&self, n: usize) -> std::slice::Chunks<'_, T> {
                self.chunks(n)
            }
        }

        pub trait ParallelSliceMut<T> {
            fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T>;
            fn par_chunks_mut(&mut self, n: usize) -> std::slice::ChunksMut<'_, T>;
            fn par_sort_unstable_by_key<K: Ord>(&mut self, f: impl Fn(&T) -> K);
        }

        impl<T> ParallelSliceMut<T> for [T] {
            fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T> {
                self.iter_mut()
            }
            fn par_chunks_mut(&mut self, n: usize) -> std::slice::ChunksMut<'_, T> {
                self.chunks_mut(n)
            }
            fn par_sort_unstable_by_key<K: Ord>(&mut self, f: impl Fn(&T) -> K) {
                self.sort_unstable_by_key(f)
            }
        }

        pub trait IntoParallelIterator: IntoIterator + Sized {
            fn into_par_iter(self) -> Self::IntoIter {
                self.into_iter()
            }
        }

        impl<T> IntoParallelIterator for std::ops::Range<T> where std::ops::Range<T>: Iterator {}
        impl<T> IntoParallelIterator for Vec<T> {}

        pub trait ParallelIterator: Iterator + Sized {
            /// `map` with a state made once by `init` (rayon makes one per
            /// job; here there is one job).
            fn map_init<S, R>(
                self,
                init: impl FnOnce() -> S,
                mut f: impl FnMut(&mut S, Self::Item) -> R,
            ) -> impl Iterator<Item = R> {
                let mut state = init();
                self.map(move |x| f(&mut state, x))
            }

            /// Items per job at most: one job here, so nothing to cut.
            fn with_max_len(self, _max: usize) -> Self {
                self
            }
        }

        impl<I: Iterator> ParallelIterator for I {}
    }
}
