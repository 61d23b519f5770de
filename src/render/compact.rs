//! Stream compaction on the host for the wavefront integrators: the items a predicate
//! keeps, in their order, written in parallel (chunks count what they keep, a prefix
//! sum places each chunk, each chunk copies its own). Chunks have a fixed size, so the
//! output never depends on the number of threads.

use rayon::prelude::*;
use std::mem::MaybeUninit;

/// Items per chunk: large enough that a chunk's work dwarfs rayon's scheduling cost,
/// small enough that a 64K-path wavefront spreads over 16 threads.
const CHUNK: usize = 4096;

/// `out` becomes `map(i, x)` for every item `x = input[i]` that `keep` accepts, in
/// order of `i` (its old contents are dropped; its allocation is reused).
pub(crate) fn compact_into<T, U>(
    input: &[T],
    out: &mut Vec<U>,
    keep: impl Fn(&T) -> bool + Sync,
    map: impl Fn(usize, &T) -> U + Sync,
) where
    T: Sync,
    U: Copy + Send,
{
    if input.len() <= CHUNK {
        // One chunk: the same items, in one pass on this thread (a path-tracing chunk's
        // wavefront, compacted three times a bounce, is never larger).
        out.clear();
        out.extend(input.iter().enumerate().filter(|(_, x)| keep(x)).map(|(i, x)| map(i, x)));
        return;
    }
    let counts: Vec<usize> = input.par_chunks(CHUNK).map(|c| c.iter().filter(|x| keep(x)).count()).collect();
    let total: usize = counts.iter().sum();
    out.clear();
    out.reserve(total);
    let mut rest = &mut out.spare_capacity_mut()[..total];
    let mut parts: Vec<&mut [MaybeUninit<U>]> = Vec::with_capacity(counts.len());
    for &c in &counts {
        let (head, tail) = rest.split_at_mut(c);
        parts.push(head);
        rest = tail;
    }
    input.par_chunks(CHUNK).zip(parts).enumerate().for_each(|(chunk, (items, part))| {
        let mut written = 0;
        for (slot, (j, x)) in part.iter_mut().zip(items.iter().enumerate().filter(|(_, x)| keep(x))) {
            slot.write(map(chunk * CHUNK + j, x));
            written += 1;
        }
        // A predicate that answered differently in the two passes would leave slots
        // unwritten: refuse rather than expose them.
        assert_eq!(written, part.len(), "compact_into: the predicate is not deterministic");
    });
    // SAFETY: the parts tile `out`'s first `total` spare slots, and every chunk wrote
    // every slot of its part (checked above; a failed check panics before this line).
    unsafe { out.set_len(total) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_what_the_predicate_keeps_in_order() {
        for n in [0, 1, CHUNK - 1, CHUNK, 3 * CHUNK + 17] {
            let input: Vec<u32> = (0..n as u32).map(|i| i.wrapping_mul(2_654_435_761)).collect();
            let mut out = vec![(7usize, 7u32); 5];
            compact_into(&input, &mut out, |x| x % 3 == 0, |i, &x| (i, x));
            let want: Vec<(usize, u32)> = input.iter().copied().enumerate().filter(|(_, x)| x % 3 == 0).collect();
            assert_eq!(out, want, "n = {n}");
        }
    }
}
