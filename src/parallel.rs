//! Parallel loops over fixed-size chunks of elements: sequential when there is only one chunk
//! (a thread-pool round trip costs more than a small model's whole step), so small and large
//! models both run at their best, and the work per element never depends on the thread count.

use rayon::prelude::*;

/// Elements per chunk (a rayon task).
pub const CHUNK: usize = 2048;

/// Calls `f(first_index, chunk)` on consecutive chunks of `CHUNK` items of `items`.
#[inline]
pub fn for_each_chunk<T: Send>(items: &mut [T], f: impl Fn(usize, &mut [T]) + Sync + Send) {
    if items.len() <= CHUNK {
        f(0, items);
    } else {
        items
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| f(c * CHUNK, chunk));
    }
}

/// Calls `f(first_index, a_chunk, b_chunk)` on matching chunks of `len` items of `a` and `b`;
/// `b` may be empty, and its chunks are then empty too.
#[inline]
pub fn for_each_chunk_pair<T: Send>(
    a: &mut [T],
    b: &mut [T],
    len: usize,
    f: impl Fn(usize, &mut [T], &mut [T]) + Sync + Send,
) {
    if a.len() <= len {
        f(0, a, b);
    } else if b.is_empty() {
        a.par_chunks_mut(len)
            .enumerate()
            .for_each(|(c, a)| f(c * len, a, &mut []));
    } else {
        a.par_chunks_mut(len)
            .zip(b.par_chunks_mut(len))
            .enumerate()
            .for_each(|(c, (a, b))| f(c * len, a, b));
    }
}
