//! The scalar kernel: one slot at a time, in the spec's order of operations (any CPU; also
//! the tail of the AVX2 kernel's small ranges).

use super::{Kernel, MINUS_X, PLUS_X};

impl Kernel {
    /// Slots `a..b` one at a time. The z = 0 slots have the substrate term h_s; the others
    /// h_s = 0.0 (exactly the value the spec's [z_i = 0] · h_s gives them, so the sum is the
    /// same).
    pub(super) unsafe fn range_scalar(&self, a: usize, b: usize) {
        let mid = self.n0.clamp(a, b);
        self.segment_scalar(a, mid, self.hs);
        self.segment_scalar(mid, b, 0.0);
    }

    /// The spec's step for one slot, in the spec's order of operations.
    #[inline(always)]
    unsafe fn slot(&self, i: usize, hs: f64) {
        let t = self.t;
        let ti = *t.add(i);
        let xf = *self.welded_faces.add(i);
        let tmx = if xf & MINUS_X != 0 {
            *t.sub(1).add(i)
        } else {
            ti
        };
        let tpx = if xf & PLUS_X != 0 { *t.add(i + 1) } else { ti };
        let tmy = *t.add(*self.ny0.add(i) as usize);
        let tpy = *t.add(*self.ny1.add(i) as usize);
        let tmz = *t.add(*self.nz0.add(i) as usize);
        let tpz = *t.add(*self.nz1.add(i) as usize);
        let h = self.h;
        let mut f = h * (tmx - ti);
        f += h * (tpx - ti);
        f += h * (tmy - ti);
        f += h * (tpy - ti);
        f += h * (tmz - ti);
        f += h * (tpz - ti);
        f += hs * (self.amb - ti);
        let tk = ti + 273.15;
        let t2 = tk * tk;
        f -= *self.radiation.add(i) * (t2 * t2 - self.q);
        *self.out.add(i) = ti + self.dt * f;
    }

    unsafe fn segment_scalar(&self, a: usize, b: usize, hs: f64) {
        for i in a..b {
            self.slot(i, hs);
        }
    }
}
