//! The steps of a step loop's driver calls: a caller that takes `n` steps in calls of at most
//! a chunk (Python's `BatchSimulation.step`, which checks for Ctrl-C between them) learns the
//! chunk from the calls' times and keeps it between its own calls, so that `step(10)` called
//! again and again is one driver call each, not one per doubling.

/// Seconds under which a whole chunk's driver call doubles the chunk.
pub const CHUNK_GROW_S: f64 = 0.1;
/// Seconds over which a driver call halves the chunk (so that a caller checking for Ctrl-C
/// between calls sees it within about half a second, even when the steps grow slower).
pub const CHUNK_SHRINK_S: f64 = 0.4;
/// The largest chunk.
pub const CHUNK_MAX: u64 = 1 << 20;

/// The chunk after a driver call of `taken` steps (of at most `chunk`) that took `seconds`:
/// doubled when a whole chunk took less than [`CHUNK_GROW_S`] (a call cut short by the steps
/// left says nothing of a whole chunk's time), halved when any call took more than
/// [`CHUNK_SHRINK_S`], else the same.
pub fn next_chunk(chunk: u64, taken: u64, seconds: f64) -> u64 {
    if seconds > CHUNK_SHRINK_S {
        (chunk / 2).max(1)
    } else if taken == chunk && seconds < CHUNK_GROW_S {
        (chunk * 2).min(CHUNK_MAX)
    } else {
        chunk
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chunk_grows_only_on_whole_quick_chunks_and_shrinks_on_slow_calls() {
        // Calls of one step: the chunk grows to 2 (a whole chunk of 1), then stays: a call of
        // one step is never a whole chunk of 2, so `step(1)` a million times cannot grow it.
        assert_eq!(next_chunk(1, 1, 0.001), 2);
        assert_eq!(next_chunk(2, 1, 0.001), 2);
        // step(10) called again and again: 1, 2, 4, 8, then 16 covers it in one call.
        let mut c = 1;
        for _ in 0..4 {
            c = next_chunk(c, c, 0.001);
        }
        assert_eq!(c, 16);
        assert_eq!(next_chunk(16, 10, 0.001), 16);
        assert_eq!(next_chunk(CHUNK_MAX, CHUNK_MAX, 0.0), CHUNK_MAX);
        // Slow calls halve it, down to one step; a call between the bounds keeps it.
        assert_eq!(next_chunk(64, 64, 0.5), 32);
        assert_eq!(next_chunk(1, 1, 5.0), 1);
        assert_eq!(next_chunk(64, 64, 0.2), 64);
    }
}
