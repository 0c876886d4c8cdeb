//! The step kernels: one explicit Euler step of the slots `a..b`, the same bits whichever
//! runs. [`Simd`] names them (chosen once per model by runtime detection), [`Kernel`] is
//! what one step reads and writes and [`Kernel::run`] dispatches to
//! - `scalar.rs`: one slot at a time, the spec's step as written (any CPU);
//! - `avx2.rs`: four slots at a time with AVX2 (x86_64);
//! - `avx512.rs`: eight slots at a time with AVX-512F (x86_64, rustc >= 1.89).
//!
//! A new kernel gets its own module, a [`Simd`] variant and an arm in [`Kernel::run`];
//! `identity.rs` then tests it bit for bit against the plain reference of the spec's step
//! (it runs every kernel of [`Simd::available`]).

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(test)]
mod identity;
mod scalar;

/// Bits of [`Simulation::welded_faces`](crate::Simulation::welded_faces): the
/// face-neighbour on that side is welded.
pub(crate) const MINUS_X: u8 = 1;
pub(crate) const PLUS_X: u8 = 2;
/// The ±y / ±z bits: [`MINUS_Y`] << d for d = 0..4 (-y, +y, -z, +z).
pub(crate) const MINUS_Y: u8 = 4;

/// Which step kernel the CPU runs (chosen once per model by runtime detection).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Simd {
    /// Plain scalar code (any CPU).
    Scalar,
    /// 4 blocks at a time with AVX2 (x86_64 only).
    Avx2,
    /// 8 blocks at a time with AVX-512F (x86_64, built with rustc >= 1.89).
    Avx512,
}

impl Simd {
    /// The best kernel this CPU supports.
    pub fn detect() -> Simd {
        #[cfg(target_arch = "x86_64")]
        {
            if Self::avx512() {
                return Simd::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Simd::Avx2;
            }
        }
        Simd::Scalar
    }

    /// Whether the AVX-512 kernel is built (rustc >= 1.89) and the CPU has AVX-512F.
    #[rustversion::since(1.89)]
    fn avx512() -> bool {
        #[cfg(target_arch = "x86_64")]
        return std::arch::is_x86_feature_detected!("avx512f");
        #[allow(unreachable_code)]
        false
    }

    #[rustversion::before(1.89)]
    fn avx512() -> bool {
        false
    }

    /// The kernels this CPU can run, best last.
    pub fn available() -> Vec<Simd> {
        let best = Simd::detect();
        [Simd::Scalar, Simd::Avx2, Simd::Avx512]
            .into_iter()
            .filter(|&s| s <= best)
            .collect()
    }
}

/// Everything one step reads and writes, as raw pointers so that threads can share it.
/// Slot `s`'s temperature is `*t.add(s)`; `t.sub(1)` and `t.add(n)` are padding.
#[derive(Clone, Copy)]
pub(crate) struct Kernel {
    pub(crate) t: *const f64,
    pub(crate) out: *mut f64,
    pub(crate) ny0: *const u32,
    pub(crate) ny1: *const u32,
    pub(crate) nz0: *const u32,
    pub(crate) nz1: *const u32,
    pub(crate) welded_faces: *const u8,
    /// Per slot its ±y / ±z neighbour slots as laid out in the part (a stand-in where the
    /// part has none), and the bits d where slots i..i + 4 have consecutive ones.
    pub(crate) near: *const [u32; 4],
    pub(crate) runs: *const u8,
    pub(crate) radiation: *const f64,
    pub(crate) h: f64,
    pub(crate) hs: f64,
    pub(crate) amb: f64,
    pub(crate) q: f64,
    pub(crate) dt: f64,
    /// Slots `0..n0` are the z = 0 blocks.
    pub(crate) n0: usize,
    pub(crate) simd: Simd,
}

// SAFETY: a `Kernel` is only used while the simulation that made it is borrowed mutably
// by `Simulation::step`, which waits for every thread before returning; the threads write
// disjoint slot ranges of `out` and only read the rest.
unsafe impl Send for Kernel {}
unsafe impl Sync for Kernel {}

impl Kernel {
    /// Steps slots `a..b` (b <= n, the part's block count).
    ///
    /// # Safety
    /// The pointers must be those of a live simulation with n slots, `a <= b <= n`, and no
    /// other thread may touch `out[a..b]`.
    pub(crate) unsafe fn run(&self, a: usize, b: usize) {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            Simd::Avx512 => return self.range_avx512(a, b),
            Simd::Avx2 => return self.range_avx2(a, b),
            Simd::Scalar => {}
        }
        self.range_scalar(a, b);
    }
}
