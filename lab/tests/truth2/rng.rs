//! The generator's random numbers (its own, shared with nothing in the project).

// ---------------------------------------------------------------------------------------
// RNG: PCG32 (O'Neill's XSH-RR, 64-bit state) seeded through SplitMix64; normals by the
// Marsaglia polar method (the second value of each accepted pair is kept for the next call).
// ---------------------------------------------------------------------------------------

/// SplitMix64 step: a well-mixed 64-bit value from a counter (used only for seeding).
pub fn splitmix64(x: &mut u64) -> u64 {
    *x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// PCG32 (XSH-RR) with a cached polar-method normal.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
    spare: Option<f64>,
}

impl Pcg32 {
    const MUL: u64 = 6_364_136_223_846_793_005;

    /// A stream for `seed` and purpose `stream`: both mixed through SplitMix64.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut s = seed ^ stream.rotate_left(32);
        let init = splitmix64(&mut s);
        let seq = splitmix64(&mut s);
        let mut r = Self { state: 0, inc: (seq << 1) | 1, spare: None };
        r.next_u32();
        r.state = r.state.wrapping_add(init);
        r.next_u32();
        r
    }

    /// Next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MUL).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// Uniform in the open interval (0, 1), 53 bits.
    pub fn uniform(&mut self) -> f64 {
        let hi = u64::from(self.next_u32() >> 5); // 27 bits
        let lo = u64::from(self.next_u32() >> 6); // 26 bits
        (((hi << 26) | lo) as f64 + 0.5) / 9_007_199_254_740_992.0
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }

    /// Log-uniform in [a, b] (a, b > 0).
    pub fn log_range(&mut self, a: f64, b: f64) -> f64 {
        (a.ln() + (b.ln() - a.ln()) * self.uniform()).exp()
    }

    /// +1 or −1 with equal probability.
    pub fn sign(&mut self) -> f64 {
        if self.next_u32() & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// An integer in 0..n.
    pub fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }

    /// Standard normal (Marsaglia polar method).
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        loop {
            let u = 2.0 * self.uniform() - 1.0;
            let v = 2.0 * self.uniform() - 1.0;
            let s = u * u + v * v;
            if s > 0.0 && s < 1.0 {
                let f = (-2.0 * s.ln() / s).sqrt();
                self.spare = Some(v * f);
                return u * f;
            }
        }
    }

    /// Student-t with 3 degrees of freedom scaled to unit SD (its variance is 3).
    pub fn student3(&mut self) -> f64 {
        let z = self.normal();
        let (a, b, c) = (self.normal(), self.normal(), self.normal());
        z / ((a * a + b * b + c * c) / 3.0).sqrt() / 3f64.sqrt()
    }
}

// Stream purposes (combined with the seed and the run).
pub(super) const S_UNIT: u64 = 0x0001;
pub(super) const S_WHITE: u64 = 0x0100;
pub(super) const S_GLITCH: u64 = 0x0200;
pub(super) const S_GM: u64 = 0x0300;
pub(super) const S_WANDER: u64 = 0x0400;
pub(super) const S_SENSOR: u64 = 0x0500;
pub(super) const S_DRAW: u64 = 0x0600;

pub(super) fn run_stream(seed: u64, purpose: u64, program: usize, run: usize) -> Pcg32 {
    Pcg32::new(seed, purpose + 16 * program as u64 + run as u64)
}

// ---------------------------------------------------------------------------------------
// The unit, the catalog and the draw.
// ---------------------------------------------------------------------------------------
