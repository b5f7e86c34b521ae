//! Parallel loops over fixed-size chunks of elements, or of a vector's numbers: sequential when
//! there is only one chunk (a thread-pool round trip costs more than a small model's whole
//! step), so small and large models both run at their best, and the work per element never
//! depends on the thread count. A chunk of numbers updated by a few operations each is
//! [`STREAM_CHUNK`] long, eight times a chunk of elements: at [`CHUNK`] numbers, a step of the
//! 1,386-cell notched beam (`examples/scenes/notched_beam.json`, local damping) went through the
//! pool for its damping and its `U` update, and ran slower on two threads than on one.

use rayon::prelude::*;

/// Elements per chunk (a rayon task).
pub const CHUNK: usize = 2048;

/// Numbers per chunk of a loop that does a few operations per number (a DOF vector's update),
/// so that a chunk's work outweighs its round trip through the pool.
pub const STREAM_CHUNK: usize = 8 * CHUNK;

/// Calls `f(first_index, chunk)` on consecutive chunks of `len` items of `items`.
#[inline]
pub fn for_each_chunk<T: Send>(
    items: &mut [T],
    len: usize,
    f: impl Fn(usize, &mut [T]) + Sync + Send,
) {
    if items.len() <= len {
        f(0, items);
    } else {
        items
            .par_chunks_mut(len)
            .enumerate()
            .for_each(|(c, chunk)| f(c * len, chunk));
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
