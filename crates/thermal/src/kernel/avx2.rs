//! The AVX2 kernel: four slots at a time (x86_64).

use super::{Kernel, MINUS_X, MINUS_Y, PLUS_X};

impl Kernel {
    /// Slots `a..b` four at a time with AVX2, in one pass: the substrate coefficient is
    /// chosen per lane (h_s below slot n0, 0.0 above, as [`Kernel::range_scalar`] has it)
    /// and a last partial vector is the vector ending at `b`, which computes some slots
    /// twice, to the same values (`out` is not read during a step).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn range_avx2(&self, a: usize, b: usize) {
        if b - a < 4 {
            return self.range_scalar(a, b);
        }
        let mut i = a;
        while i + 4 <= b {
            self.lanes_avx2(i);
            i += 4;
        }
        if i < b {
            self.lanes_avx2(b - 4);
        }
    }

    /// Slots `i..i + 4` (`i + 4 <= n`): the same operations in the same order on each lane
    /// as [`Kernel::slot`] (AVX2 adds, subtracts and multiplies are the IEEE operations of
    /// the scalar code; there is no fused multiply-add). The ±x neighbours are the
    /// contiguous reads beside the slots; a ±y / ±z neighbour is one load where the four
    /// slots' neighbours are consecutive (see
    /// [`neighbour_runs`](crate::model::neighbour_runs)), else a gather; either way the
    /// slot's own value stands in for an unwelded neighbour.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn lanes_avx2(&self, i: usize) {
        use std::arch::x86_64::*;
        let t = self.t;
        let ti = _mm256_loadu_pd(t.add(i));
        let faces = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(
            (self.welded_faces.add(i) as *const i32).read_unaligned(),
        ));
        macro_rules! welded {
            ($bit:expr) => {{
                let bit = _mm256_set1_epi64x($bit as i64);
                _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(faces, bit), bit))
            }};
        }
        let tmx = _mm256_blendv_pd(ti, _mm256_loadu_pd(t.sub(1).add(i)), welded!(MINUS_X));
        let tpx = _mm256_blendv_pd(ti, _mm256_loadu_pd(t.add(i + 1)), welded!(PLUS_X));
        let runs = *self.runs.add(i);
        let near = &*self.near.add(i);
        macro_rules! neighbour {
            ($d:expr, $slots:expr) => {
                if runs & (1 << $d) != 0 {
                    let v = _mm256_loadu_pd(t.add(near[$d] as usize));
                    _mm256_blendv_pd(ti, v, welded!(MINUS_Y << $d))
                } else {
                    let idx = _mm_loadu_si128($slots.add(i) as *const __m128i);
                    _mm256_i32gather_pd::<8>(t, idx)
                }
            };
        }
        let tmy = neighbour!(0, self.ny0);
        let tpy = neighbour!(1, self.ny1);
        let tmz = neighbour!(2, self.nz0);
        let tpz = neighbour!(3, self.nz1);
        // h_s on the lanes below slot n0, +0.0 on the others.
        let hs_v = if i >= self.n0 {
            _mm256_setzero_pd()
        } else {
            let lane = _mm256_setr_epi64x(i as i64, i as i64 + 1, i as i64 + 2, i as i64 + 3);
            let below = _mm256_cmpgt_epi64(_mm256_set1_epi64x(self.n0 as i64), lane);
            _mm256_and_pd(_mm256_castsi256_pd(below), _mm256_set1_pd(self.hs))
        };
        let h = _mm256_set1_pd(self.h);
        let mut f = _mm256_mul_pd(h, _mm256_sub_pd(tmx, ti));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tpx, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tmy, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tpy, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tmz, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tpz, ti)));
        f = _mm256_add_pd(
            f,
            _mm256_mul_pd(hs_v, _mm256_sub_pd(_mm256_set1_pd(self.amb), ti)),
        );
        let tk = _mm256_add_pd(ti, _mm256_set1_pd(273.15));
        let t2 = _mm256_mul_pd(tk, tk);
        let re = _mm256_loadu_pd(self.radiation.add(i));
        f = _mm256_sub_pd(
            f,
            _mm256_mul_pd(
                re,
                _mm256_sub_pd(_mm256_mul_pd(t2, t2), _mm256_set1_pd(self.q)),
            ),
        );
        let out = _mm256_add_pd(ti, _mm256_mul_pd(_mm256_set1_pd(self.dt), f));
        _mm256_storeu_pd(self.out.add(i), out);
    }
}
