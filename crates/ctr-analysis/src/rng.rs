//! The project's one seeded random generator (the IK's start table, synthetic
//! recordings, and whatever draws samples next): splitmix64, so that a seed fixes the
//! numbers on every machine.

/// A small seeded random generator: splitmix64 (Steele, Lea and Flood 2014), uniform
/// numbers from its top 53 bits and normal ones by the Box-Muller transform. Not for
/// cryptography; here so that a seed fixes a start table or a recording.
///
/// ```
/// let mut a = ctr_analysis::rng::Rng::new(42);
/// let mut b = ctr_analysis::rng::Rng::new(42);
/// assert_eq!(a.next_u64(), b.next_u64());
/// let u = a.uniform();
/// assert!((0.0..1.0).contains(&u));
/// let mean = (0..10_000).map(|_| a.normal()).sum::<f64>() / 10_000.0;
/// assert!(mean.abs() < 0.05);
/// ```
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    spare: Option<f64>,
}

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng {
            state: seed,
            spare: None,
        }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform on `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        const MANTISSA_BITS: u32 = 53;
        (self.next_u64() >> (64 - MANTISSA_BITS)) as f64 / (1u64 << MANTISSA_BITS) as f64
    }

    /// Standard normal (mean 0, standard deviation 1).
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // 1 - u is in (0, 1]: the logarithm stays finite
        let r = (-2.0 * (1.0 - self.uniform()).ln()).sqrt();
        let phi = std::f64::consts::TAU * self.uniform();
        self.spare = Some(r * phi.sin());
        r * phi.cos()
    }

    /// A uniformly random unit vector.
    pub fn unit_vector(&mut self) -> [f64; 3] {
        loop {
            let v = [self.normal(), self.normal(), self.normal()];
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if n > f64::EPSILON {
                return [v[0] / n, v[1] / n, v[2] / n];
            }
        }
    }

    /// An index in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }
}
