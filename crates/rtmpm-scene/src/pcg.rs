//! The sampling's random stream as plain numbers: `rand_pcg::Pcg64` (PCG XSL RR 128/64, O'Neill,
//! "PCG: A Family of Simple Fast Space-Efficient Statistically Good Algorithms for Random Number
//! Generation", 2014) seeded by `SeedableRng::seed_from_u64` and drawn as `rng.random::<f32>()`
//! (rand 0.9), with its state and increment readable, so that a GPU can draw the numbers the
//! host's walk draws (`rtmpm-cuda/kernels/sample.cuh` is the device's copy of these formulas).
//! The unit tests hold it to `rand_pcg` bit for bit.

/// The LCG multiplier of PCG 128/64.
pub const MULTIPLIER: u128 = 0x2360_ED05_1FC6_5DA4_4385_DF64_9FCC_F645;

/// One PCG 128/64 stream: the 128-bit LCG state and its (odd) increment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PcgStream {
    pub state: u128,
    pub increment: u128,
}

impl PcgStream {
    /// The stream of `rand_pcg::Pcg64::seed_from_u64(seed)`: rand_core 0.9 expands the seed into
    /// 32 bytes with PCG32, rand_pcg reads state and increment from them, adds the increment and
    /// steps once.
    pub fn seed_from_u64(seed: u64) -> PcgStream {
        let mut s = seed;
        let mut bytes = [0u8; 32];
        for chunk in bytes.chunks_exact_mut(4) {
            // rand_core's PCG32 expansion: step, then the XSH RR output.
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(11634580027462260723);
            let xorshifted = (((s >> 18) ^ s) >> 27) as u32;
            let rot = (s >> 59) as u32;
            chunk.copy_from_slice(&xorshifted.rotate_right(rot).to_le_bytes());
        }
        let word = |k: usize| {
            let mut w = [0u8; 16];
            w.copy_from_slice(&bytes[16 * k..16 * k + 16]);
            u128::from_le_bytes(w)
        };
        let increment = word(1) | 1;
        let mut p = PcgStream {
            state: word(0).wrapping_add(increment),
            increment,
        };
        p.step();
        p
    }

    fn step(&mut self) {
        self.state = self
            .state
            .wrapping_mul(MULTIPLIER)
            .wrapping_add(self.increment);
    }

    /// Jump `delta` steps ahead in O(log delta) (Brown, "Random number generation with arbitrary
    /// strides", 1994), as `Pcg64::advance`.
    pub fn advance(&mut self, delta: u128) {
        let (mut acc_mult, mut acc_plus) = (1u128, 0u128);
        let (mut cur_mult, mut cur_plus) = (MULTIPLIER, self.increment);
        let mut d = delta;
        while d > 0 {
            if d & 1 != 0 {
                acc_mult = acc_mult.wrapping_mul(cur_mult);
                acc_plus = acc_plus.wrapping_mul(cur_mult).wrapping_add(cur_plus);
            }
            cur_plus = cur_mult.wrapping_add(1).wrapping_mul(cur_plus);
            cur_mult = cur_mult.wrapping_mul(cur_mult);
            d /= 2;
        }
        self.state = acc_mult.wrapping_mul(self.state).wrapping_add(acc_plus);
    }

    /// The next 64 bits: step, then the XSL RR output of the new state.
    pub fn next_u64(&mut self) -> u64 {
        self.step();
        let rot = (self.state >> 122) as u32;
        let xsl = ((self.state >> 64) as u64) ^ (self.state as u64);
        xsl.rotate_right(rot)
    }

    /// `rng.random::<f32>()` of rand 0.9: the top 24 of the low 32 bits, times 2^-24 (in [0, 1)).
    pub fn next_f32(&mut self) -> f32 {
        ((self.next_u64() as u32) >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, RngCore, SeedableRng};
    use rand_pcg::Pcg64;

    #[test]
    fn the_stream_is_rand_pcg_s_bit_for_bit() {
        for seed in [0u64, 1, 42, 0x9E37_79B9_7F4A_7C15, u64::MAX] {
            let mut ours = PcgStream::seed_from_u64(seed);
            let mut theirs = Pcg64::seed_from_u64(seed);
            for _ in 0..1000 {
                assert_eq!(ours.next_u64(), theirs.next_u64(), "seed {seed}");
            }
            for _ in 0..1000 {
                assert_eq!(
                    ours.next_f32().to_bits(),
                    theirs.random::<f32>().to_bits(),
                    "seed {seed}"
                );
            }
        }
    }

    #[test]
    fn advance_is_rand_pcg_s_jump() {
        for (seed, delta) in [(7u64, 1u128), (7, 3 * 12345), (99, 1 << 40), (3, 0)] {
            let mut ours = PcgStream::seed_from_u64(seed);
            let mut theirs = Pcg64::seed_from_u64(seed);
            ours.advance(delta);
            theirs.advance(delta);
            for _ in 0..10 {
                assert_eq!(ours.next_u64(), theirs.next_u64());
            }
            // A jump is the same as stepping.
            let mut stepped = PcgStream::seed_from_u64(seed);
            let mut jumped = stepped;
            let k = (delta % 5000) as usize;
            for _ in 0..k {
                stepped.next_u64();
            }
            jumped.advance(k as u128);
            assert_eq!(stepped, jumped);
        }
    }
}
