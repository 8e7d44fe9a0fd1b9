//! The little-endian writer and reader of the stored layouts (the parameter record's and the run
//! records'), over buffers whose length was checked up front.

use crate::kinematics::geometry::Geometry;
use crate::motion::speed::MotorParams;

/// Little-endian writer over a fixed buffer whose length was checked up front.
pub(in crate::storage) struct Writer<'a> {
    pub(in crate::storage) buf: &'a mut [u8],
    pub(in crate::storage) pos: usize,
}

impl Writer<'_> {
    // Out of line, like `Reader::fill`.
    #[inline(never)]
    pub(in crate::storage) fn bytes(&mut self, b: &[u8]) {
        if let Some(dst) = self.buf.get_mut(self.pos..self.pos + b.len()) {
            dst.copy_from_slice(b);
        }
        self.pos += b.len();
    }
    pub(in crate::storage) fn f64(&mut self, v: f64) {
        self.bytes(&v.to_le_bytes());
    }
    pub(in crate::storage) fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }
    pub(in crate::storage) fn geometry(&mut self, g: &Geometry) {
        self.f64(g.diameter_right_m);
        self.f64(g.diameter_left_m);
        self.f64(g.wheelbase_m);
        self.bytes(&g.counts_per_rev.to_le_bytes());
    }
    pub(super) fn motor(&mut self, m: &MotorParams) {
        self.f32(m.gain_forward_mps);
        self.f32(m.gain_backward_mps);
        self.f32(m.time_constant_s);
        self.f32(m.deadband);
    }
}

/// Little-endian reader over a buffer whose length was checked up front.
pub(in crate::storage) struct Reader<'a> {
    pub(in crate::storage) buf: &'a [u8],
    pub(in crate::storage) pos: usize,
}

impl Reader<'_> {
    pub(in crate::storage) fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        self.fill(&mut out);
        out
    }
    /// Copies the next `out.len()` bytes (left zero past the end). Out of line: one copy for
    /// the twenty-odd fields instead of one per field.
    #[inline(never)]
    pub(in crate::storage) fn fill(&mut self, out: &mut [u8]) {
        if let Some(src) = self.buf.get(self.pos..self.pos + out.len()) {
            out.copy_from_slice(src);
        }
        self.pos += out.len();
    }
    pub(in crate::storage) fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.array())
    }
    pub(in crate::storage) fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.array())
    }
    pub(in crate::storage) fn geometry(&mut self) -> Geometry {
        Geometry {
            diameter_right_m: self.f64(),
            diameter_left_m: self.f64(),
            wheelbase_m: self.f64(),
            counts_per_rev: u32::from_le_bytes(self.array()),
        }
    }
    pub(super) fn motor(&mut self) -> MotorParams {
        MotorParams {
            gain_forward_mps: self.f32(),
            gain_backward_mps: self.f32(),
            time_constant_s: self.f32(),
            deadband: self.f32(),
        }
    }
}
