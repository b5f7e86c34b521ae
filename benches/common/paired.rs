//! What the benches that compare cases sample by sample share (`failure`, `formulations`): the
//! size they stop at, thread pools, quartiles and the median of paired ratios.
// Each bench includes this module and uses part of it.
#![allow(dead_code)]

/// `RBSM_BENCH_MAX`: the largest model a partial run measures (all when unset).
pub fn max_elements() -> usize {
    std::env::var("RBSM_BENCH_MAX")
        .ok()
        .and_then(|m| m.parse::<f64>().ok())
        .map_or(usize::MAX, |x| x as usize)
}

/// A pool of `threads` worker threads.
pub fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
}

/// The first quartile, the median and the third quartile of `s`.
pub fn quartiles(mut s: Vec<f64>) -> [f64; 3] {
    s.sort_by(f64::total_cmp);
    [1, 2, 3].map(|k| s[(k * s.len() / 4).min(s.len() - 1)])
}

/// The median over samples of `samples[k] / samples[0]`: a case against the first, sample by
/// sample (a shared machine drifts between samples).
pub fn paired(samples: &[Vec<f64>], k: usize) -> f64 {
    let ratios = samples[k]
        .iter()
        .zip(&samples[0])
        .map(|(x, e)| x / e)
        .collect();
    quartiles(ratios)[1]
}
