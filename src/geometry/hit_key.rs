//! Closest-hit keys: a hit's distance in the high 32 bits and its triangle's id in the
//! low 32, so that the smaller key is the closer hit, and of two hits at one distance
//! the one with the smaller id (distances are non-negative, and the bits of
//! non-negative floats order as the numbers do). A key fits one 64-bit atomic minimum,
//! which is how the divide-and-conquer casters' leaves (DACRT on the CPU, PDACRT's
//! kernels and its CUDA twin's `pack_hit`) keep a ray's closest hit: one rule, here.

/// No hit yet.
pub const NONE: u64 = u64::MAX;

/// Any-hit queries: the ray is known to be blocked (below every real key).
pub const BLOCKED: u64 = 0;

/// The key of a hit at distance `t` (non-negative) on triangle `prim`.
#[inline]
pub fn pack(t: f32, prim: u32) -> u64 {
    (t.to_bits() as u64) << 32 | prim as u64
}

/// The distance a key holds.
#[inline]
pub fn t_of(key: u64) -> f32 {
    f32::from_bits((key >> 32) as u32)
}

/// The triangle a key names.
#[inline]
pub fn prim_of(key: u64) -> u32 {
    (key & 0xffff_ffff) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_order_by_distance_then_id_and_round_trip() {
        assert!(pack(1.0, 7) < pack(1.5, 0));
        assert!(pack(2.0, 3) < pack(2.0, 4));
        // A hit at distance 0 on triangle 0 has BLOCKED's bits; the two never meet:
        // BLOCKED serves any-hit queries only.
        assert_eq!(pack(0.0, 0), BLOCKED);
        assert!(pack(f32::MAX, u32::MAX - 1) < NONE);
        let k = pack(0.3125, 123_456);
        assert_eq!((t_of(k), prim_of(k)), (0.3125, 123_456));
    }
}
