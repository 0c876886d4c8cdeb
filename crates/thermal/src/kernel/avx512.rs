//! The AVX-512F kernel: eight slots at a time (x86_64, built with rustc >= 1.89; before,
//! [`Kernel::range_avx512`] is the AVX2 kernel and [`Simd::detect`](super::Simd::detect)
//! never picks it).

use super::{Kernel, MINUS_X, PLUS_X};

impl Kernel {
    /// Slots `a..b` eight at a time in one pass, as [`Kernel::lanes_avx2`] but with the
    /// substrate coefficient per lane (h_s on the z = 0 slots, 0.0 on the others, as
    /// [`Kernel::run`] gives them) and the last, partial vector masked: a small part's step
    /// is a handful of vectors, and the two segments' AVX2 and scalar tails showed in its
    /// profile (ex3 `--all --threads 1`: about 3 % less CPU in all).
    #[cfg(target_arch = "x86_64")]
    #[rustversion::since(1.89)]
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn range_avx512(&self, a: usize, b: usize) {
        let mut i = a;
        while i + 8 <= b {
            let idx = [self.ny0, self.ny1, self.nz0, self.nz1].map(|p| p.add(i));
            self.lanes_avx512(i, 0xff, self.welded_faces.add(i), idx);
            i += 8;
        }
        if i < b {
            // The index arrays end at slot n: the last lanes read copies, padded with
            // slot i itself (a valid slot, read by gathers whose results are not stored).
            let m = b - i;
            let mut xflags = [0u8; 8];
            std::ptr::copy_nonoverlapping(self.welded_faces.add(i), xflags.as_mut_ptr(), m);
            let mut idx = [[i as u32; 8]; 4];
            for (buf, p) in idx.iter_mut().zip([self.ny0, self.ny1, self.nz0, self.nz1]) {
                std::ptr::copy_nonoverlapping(p.add(i), buf.as_mut_ptr(), m);
            }
            let mask = (1u8 << m) - 1;
            self.lanes_avx512(i, mask, xflags.as_ptr(), idx.each_ref().map(|b| b.as_ptr()));
        }
    }

    /// The lanes of `mask` of slots `i..i + 8`; `xflags` and `idx` (±y, ±z neighbours)
    /// point at those slots' entries.
    #[cfg(target_arch = "x86_64")]
    #[rustversion::since(1.89)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn lanes_avx512(&self, i: usize, mask: u8, xflags: *const u8, idx: [*const u32; 4]) {
        use std::arch::x86_64::*;
        let t = self.t;
        let h = _mm512_set1_pd(self.h);
        // h_s on the z = 0 lanes, +0.0 on the others.
        let substrate = match self.n0.saturating_sub(i) {
            0 => 0u8,
            n if n >= 8 => 0xff,
            n => (1u8 << n) - 1,
        };
        let hs_v = _mm512_maskz_mov_pd(substrate, _mm512_set1_pd(self.hs));
        let amb = _mm512_set1_pd(self.amb);
        let q = _mm512_set1_pd(self.q);
        let dt = _mm512_set1_pd(self.dt);
        let kelvin = _mm512_set1_pd(273.15);
        let bit_mx = _mm512_set1_epi64(MINUS_X as i64);
        let bit_px = _mm512_set1_epi64(PLUS_X as i64);
        let ti = _mm512_maskz_loadu_pd(mask, t.add(i));
        let xf = _mm512_cvtepu8_epi64(_mm_loadl_epi64(xflags as *const __m128i));
        let m_mx = _mm512_test_epi64_mask(xf, bit_mx) & mask;
        let m_px = _mm512_test_epi64_mask(xf, bit_px) & mask;
        let tmx = _mm512_mask_loadu_pd(ti, m_mx, t.sub(1).add(i));
        let tpx = _mm512_mask_loadu_pd(ti, m_px, t.add(i + 1));
        let gather =
            |p: *const u32| _mm512_i32gather_pd::<8>(_mm256_loadu_si256(p as *const __m256i), t);
        let tmy = gather(idx[0]);
        let tpy = gather(idx[1]);
        let tmz = gather(idx[2]);
        let tpz = gather(idx[3]);
        let mut f = _mm512_mul_pd(h, _mm512_sub_pd(tmx, ti));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tpx, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tmy, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tpy, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tmz, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tpz, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(hs_v, _mm512_sub_pd(amb, ti)));
        let tk = _mm512_add_pd(ti, kelvin);
        let t2 = _mm512_mul_pd(tk, tk);
        let re = _mm512_maskz_loadu_pd(mask, self.radiation.add(i));
        f = _mm512_sub_pd(
            f,
            _mm512_mul_pd(re, _mm512_sub_pd(_mm512_mul_pd(t2, t2), q)),
        );
        _mm512_mask_storeu_pd(
            self.out.add(i),
            mask,
            _mm512_add_pd(ti, _mm512_mul_pd(dt, f)),
        );
    }

    /// Before rustc 1.89 there is no AVX-512 kernel
    /// ([`Simd::detect`](super::Simd::detect) never picks it).
    #[cfg(target_arch = "x86_64")]
    #[rustversion::before(1.89)]
    pub(super) unsafe fn range_avx512(&self, a: usize, b: usize) {
        self.range_avx2(a, b)
    }
}
