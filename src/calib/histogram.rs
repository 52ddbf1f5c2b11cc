//! A fixed-size histogram for medians of positive values (no heap, no sort).

/// A median of positive values to 1 % from 256 log-spaced bins between 1e-5 and 100 m.
pub(crate) struct Histogram {
    bins: [u32; 256],
    n: u32,
}

impl Histogram {
    const LO: f64 = 1e-5;
    const DECADES: f64 = 7.0;
    /// Empty.
    pub(crate) fn new() -> Self {
        Self {
            bins: [0; 256],
            n: 0,
        }
    }
    /// One value more.
    pub(crate) fn add(&mut self, v: f64) {
        let x = libm::log10(v.max(Self::LO) / Self::LO) / Self::DECADES * 256.0;
        let i = if x.is_finite() {
            (x as usize).min(255)
        } else {
            255
        };
        self.bins[i] += 1;
        self.n += 1;
    }
    /// Values added.
    pub(crate) fn count(&self) -> u32 {
        self.n
    }

    /// The median of the values added (the bin's middle).
    pub(crate) fn median(&self) -> f64 {
        let mut acc = 0;
        for (i, &c) in self.bins.iter().enumerate() {
            acc += c;
            if 2 * acc >= self.n {
                return Self::LO * libm::pow(10.0, (i as f64 + 0.5) / 256.0 * Self::DECADES);
            }
        }
        Self::LO * libm::pow(10.0, Self::DECADES)
    }
}
