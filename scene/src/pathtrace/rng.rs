//! Counter-based random numbers: the `d`-th uniform number of sample `s` of pixel `p` is a hash of
//! `(seed, p, s, d)` (the idea of Salmon et al. 2011, "Parallel random numbers: as easy as 1, 2, 3",
//! with the SplitMix64 finaliser of Steele et al. 2014 as the mixing function).
//!
//! Every path vertex reads fixed dimensions whatever the renderer decides to skip, so a render that
//! skips an effect the scene cannot show uses exactly the same numbers as one that simulates it, and
//! the two images can be compared pixel for pixel. Thread scheduling cannot change an image either.

/// The random numbers of one pixel sample.
#[derive(Clone, Copy, Debug)]
pub struct SampleRng {
    key: u64,
}

/// SplitMix64's output function (Steele, Lea & Flood 2014).
#[inline]
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl SampleRng {
    /// The stream of sample `sample` of pixel `pixel` under `seed`.
    #[inline]
    pub fn new(seed: u64, pixel: u64, sample: u64) -> Self {
        SampleRng { key: mix(mix(mix(seed) ^ pixel) ^ sample) }
    }

    /// Uniform number `dim` of this sample, in [0, 1) with 24 random bits (exactly representable).
    ///
    /// ```
    /// use nbrdf_scene::pathtrace::rng::SampleRng;
    /// let r = SampleRng::new(7, 3, 1);
    /// assert_eq!(r.get(5), SampleRng::new(7, 3, 1).get(5)); // a pure function of its inputs
    /// assert!((0.0..1.0).contains(&r.get(5)) && r.get(5) != r.get(6));
    /// ```
    #[inline]
    pub fn get(&self, dim: u32) -> f32 {
        (mix(self.key ^ dim as u64) >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
}
