//! Frame step `film`, its scheduling: a chain of whole-image passes (the temporal filter's
//! bands, then the a-trous filter's prepass and passes) run over the thread pool band by
//! band, a band of one pass starting as soon as the bands of the pass before it that it
//! reads are done.
//!
//! Run one pass at a time, every thread waited at each pass's end for the slowest band
//! of it, and the next pass's workers were woken again: on first-light at 640 x 360, half
//! scale, two threads, the spatial filter's three passes left a core idle for 0.13 ms of
//! their 1.06 ms (their bands' summed time against twice the passes' wall time). Chained,
//! a thread that finds no band of a pass left goes on to the next: the spatial filter's
//! p50 fell 1.018 -> 0.912 ms there, 1.155 -> 1.009 on the-gallery and 1.271 -> 1.187 on
//! the-keep (`gloam bench`, medians of 3 or 4 alternated runs), the same on one thread.
//! The temporal pass, which idled a core 0.1 ms a frame at its end, joined the chain:
//! temporal + spatial 1.935 -> 1.755 ms on first-light, 2.246 -> 2.066 on the-gallery and
//! 2.449 -> 2.174 on the-keep against passes run one at a time (3 alternated runs).
//!
//! Each thread has a home segment of the bands, the same rows in every pass, which it
//! takes from the front in order; with its own segment taken, it takes bands from the back
//! of the others' (the last a segment's owner would reach), and then goes on to the next
//! pass. So a band's neighbours, whose rows its taps read, were mostly written by the same
//! core: bands handed out in turn from one counter alternated between the two cores, and
//! the passes' own time rose 11 to 15% (halo rows fetched from the other core's cache).
//!
//! A band of pass p waits until the bands of pass p - 1 within `reach[p]` of its own are
//! done. That cannot deadlock: a thread goes on to pass p + 1 only once every band of pass
//! p has been taken, and a band is run by the thread that took it, at once, so every band
//! waited for is being run. Each pixel is computed as it is pass by pass, so the result
//! does not depend on the thread count.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

/// Runs `task(state, pass, band)` once for every pass `0..reach.len()` and band
/// `0..bands`, on the current rayon pool's threads (each with its own `init()` state),
/// band (pass, b) only after bands (pass - 1, b - reach[pass] ..= b + reach[pass]) have
/// finished (`reach[0]` is not read). Whatever a band writes, the bands after it that
/// wait for it see. Returns each pass's CPU seconds, its bands' times summed.
pub(crate) fn run_chain<S>(
    bands: usize,
    reach: &[usize],
    init: impl Fn() -> S + Sync,
    task: impl Fn(&mut S, usize, usize) + Sync,
) -> Vec<f64> {
    let passes = reach.len();
    if bands == 0 || passes == 0 {
        return vec![0.0; passes];
    }
    let nanoseconds: Vec<AtomicU64> = (0..passes).map(|_| AtomicU64::new(0)).collect();
    let workers = rayon::current_num_threads().clamp(1, bands);
    let done: Vec<AtomicBool> = (0..bands * passes)
        .map(|_| AtomicBool::new(false))
        .collect();
    // Per pass and worker, the segment's bands not yet taken.
    let segments: Vec<Segment> = (0..passes)
        .flat_map(|_| {
            (0..workers).map(move |worker| {
                Segment::new(worker * bands / workers..(worker + 1) * bands / workers)
            })
        })
        .collect();
    let work = |worker: usize| {
        let mut state = None;
        for pass in 0..passes {
            let segments = &segments[pass * workers..(pass + 1) * workers];
            let others = (1..workers).map(|offset| &segments[(worker + offset) % workers]);
            let own = std::iter::from_fn(|| segments[worker].take_front());
            let stolen = others.flat_map(|segment| std::iter::from_fn(|| segment.take_back()));
            for band in own.chain(stolen) {
                if pass > 0 {
                    let before = &done[(pass - 1) * bands..pass * bands];
                    let reach = reach[pass];
                    let read = band.saturating_sub(reach)..=(band + reach).min(bands - 1);
                    before[read].iter().for_each(wait_for);
                }
                let start = Instant::now();
                task(state.get_or_insert_with(&init), pass, band);
                let spent = start.elapsed().as_nanos().try_into().unwrap_or(u64::MAX);
                nanoseconds[pass].fetch_add(spent, Ordering::Relaxed);
                // Release: the band's writes happen before any wait that sees it done.
                done[pass * bands + band].store(true, Ordering::Release);
            }
        }
    };
    rayon::scope(|scope| {
        for worker in 1..workers {
            scope.spawn(move |_| work(worker));
        }
        work(0);
    });
    (nanoseconds.iter())
        .map(|spent| spent.load(Ordering::Relaxed) as f64 * 1e-9)
        .collect()
}

/// A run of bands taken from either end: the next band at the front (low 32 bits) and
/// the end of the run (high 32 bits), in one atomic word.
struct Segment(AtomicU64);

impl Segment {
    fn new(bands: std::ops::Range<usize>) -> Segment {
        Segment(AtomicU64::new(
            bands.start as u64 | (bands.end as u64) << 32,
        ))
    }

    fn take_front(&self) -> Option<usize> {
        self.take(|front, end| (front, front + 1, end))
    }

    fn take_back(&self) -> Option<usize> {
        self.take(|front, end| (end - 1, front, end - 1))
    }

    /// Takes a band as `split(front, end)` says (the band, the new front and end), if the
    /// segment has one left.
    fn take(&self, split: impl Fn(u64, u64) -> (u64, u64, u64)) -> Option<usize> {
        let mut current = self.0.load(Ordering::Relaxed);
        loop {
            let (front, end) = (current & u64::from(u32::MAX), current >> 32);
            if front >= end {
                return None;
            }
            let (band, front, end) = split(front, end);
            match self.0.compare_exchange_weak(
                current,
                front | end << 32,
                Ordering::Relaxed,
                Ordering::Relaxed,
            ) {
                Ok(_) => return Some(band as usize),
                Err(now) => current = now,
            }
        }
    }
}

/// Spins until `done` is set (then sees the writes of the band that set it). The wait is
/// short, a band of the pass before being run already: a thread gives up its core only
/// when it is long (more threads than cores).
fn wait_for(done: &AtomicBool) {
    let mut spins = 0u32;
    while !done.load(Ordering::Acquire) {
        if spins < 1 << 12 {
            spins += 1;
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;
    use std::sync::atomic::AtomicUsize;

    /// Every band of every pass runs once, and only after the bands it reads: each band
    /// records the finishing order, and every band of the pass before within its reach
    /// finished earlier. On several threads and on one.
    #[test]
    fn each_band_runs_once_after_the_bands_it_reads() {
        for threads in [1, 2, 4] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let (bands, reach) = (23, [0, 1, 2, 1]);
            let finished = Mutex::new(Vec::new());
            let states = AtomicUsize::new(0);
            pool.install(|| {
                run_chain(
                    bands,
                    &reach,
                    || states.fetch_add(1, Ordering::Relaxed),
                    |_, pass, band| {
                        // Uneven bands, so threads overtake one another.
                        let spin = (band * 7919 + pass * 104_729) % 5000;
                        for _ in 0..spin {
                            std::hint::spin_loop();
                        }
                        finished.lock().expect("no panics").push((pass, band));
                    },
                )
            });
            let finished = finished.into_inner().expect("no panics");
            assert_eq!(finished.len(), bands * reach.len(), "{threads} threads");
            let position = |pass: usize, band: usize| {
                finished
                    .iter()
                    .position(|&done| done == (pass, band))
                    .unwrap_or_else(|| panic!("band ({pass}, {band}) never ran"))
            };
            for (pass, &reach) in reach.iter().enumerate().skip(1) {
                for band in 0..bands {
                    let (low, high) = (band.saturating_sub(reach), (band + reach).min(bands - 1));
                    for read in low..=high {
                        assert!(
                            position(pass - 1, read) < position(pass, band),
                            "band ({pass}, {band}) ran before ({}, {read}) finished",
                            pass - 1
                        );
                    }
                }
            }
            assert!(states.load(Ordering::Relaxed) <= threads);
        }
    }
}
