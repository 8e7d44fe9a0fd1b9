//! The online statistics of one wheel: exact integer sums of the block pairs of the segment being
//! driven, and of each finished segment only the means and centred moments the fit needs.

use super::plan::Segment;

/// Exact integer sums of the block pairs `(x, y)` of the segment being driven.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Running {
    pub(super) n: u32,
    pub(super) sx: i64,
    pub(super) sy: i64,
    pub(super) sxx: i64,
    pub(super) sxy: i64,
    pub(super) syy: i64,
}

/// Means and centred second moments of a segment's pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Moments {
    pub(super) n: f64,
    pub(super) mx: f64,
    pub(super) my: f64,
    pub(super) cxx: f64,
    pub(super) cxy: f64,
    pub(super) cyy: f64,
}

impl Running {
    pub(super) fn add(&mut self, x: i64, y: i64) {
        self.n += 1;
        self.sx += x;
        self.sy += y;
        // A block count is below 2 m/s for 10 ms (the routine stops faster wheels), so the
        // sums of products stay far inside i64; saturating all the same.
        self.sxx = self.sxx.saturating_add(x.saturating_mul(x));
        self.sxy = self.sxy.saturating_add(x.saturating_mul(y));
        self.syy = self.syy.saturating_add(y.saturating_mul(y));
    }

    pub(super) fn moments(&self) -> Moments {
        if self.n == 0 {
            return Moments::default();
        }
        let n = f64::from(self.n);
        let (sx, sy) = (self.sx as f64, self.sy as f64);
        Moments {
            n,
            mx: sx / n,
            my: sy / n,
            cxx: self.sxx as f64 - sx * sx / n,
            cxy: self.sxy as f64 - sx * sy / n,
            cyy: self.syy as f64 - sy * sy / n,
        }
    }
}

/// What is kept of one wheel: the running sums of the current segment, and of each finished
/// segment only what the fit needs (160 B per wheel).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct WheelLog {
    pub(super) running: Running,
    /// Centred moments `(Σxx, Σxy, Σyy)` of all duty steps, each about its own means.
    pub(super) pooled: (f64, f64, f64),
    /// Pairs and steps in `pooled`.
    pub(super) pairs: u32,
    pub(super) steps: u32,
    /// Means `(x̄, ȳ)` of each duty step, per direction.
    pub(super) step_means: [[(f32, f32); 3]; 2],
    /// Coast per direction: `Σxx`, `Σxy` (centred), `x̄`, `ȳ`.
    pub(super) coast: [[f32; 4]; 2],
}

impl WheelLog {
    /// Keeps what the fit needs of the finished `seg` of direction `dir`, and clears the sums.
    /// Once per finished segment, not per period; `f64` because the centred moments subtract
    /// sums of squares (up to ~1e10 over a step's blocks) whose difference `f32` would keep to a
    /// few digits.
    pub(super) fn close(&mut self, seg: Segment, dir: usize) {
        let m = self.running.moments();
        self.running = Running::default();
        match seg {
            Segment::Level(i) => {
                if m.n < 2.0 {
                    return;
                }
                self.pooled.0 += m.cxx;
                self.pooled.1 += m.cxy;
                self.pooled.2 += m.cyy;
                self.pairs += m.n as u32;
                self.steps += 1;
                if let Some(s) = self.step_means.get_mut(dir).and_then(|d| d.get_mut(i)) {
                    *s = (m.mx as f32, m.my as f32);
                }
            }
            Segment::Coast => {
                if let Some(c) = self.coast.get_mut(dir) {
                    *c = [m.cxx as f32, m.cxy as f32, m.mx as f32, m.my as f32];
                }
            }
            Segment::Brake => {}
        }
    }
}
