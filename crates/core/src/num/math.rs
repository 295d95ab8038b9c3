//! Elementary functions through libm, so results are identical with and without `std`.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    libm::exp(x)
}
#[inline(always)]
pub fn expm1(x: f64) -> f64 {
    libm::expm1(x)
}
#[inline(always)]
pub fn tanh(x: f64) -> f64 {
    libm::tanh(x)
}
#[inline(always)]
pub fn atanh(x: f64) -> f64 {
    libm::atanh(x)
}
#[inline(always)]
pub fn pow(x: f64, y: f64) -> f64 {
    libm::pow(x, y)
}
#[inline(always)]
pub fn sqrt(x: f64) -> f64 {
    libm::sqrt(x)
}
#[inline(always)]
pub fn abs(x: f64) -> f64 {
    libm::fabs(x)
}
/// Sign with `sign(0) = 0`.
#[inline(always)]
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}
/// The play operator's clamp, written with comparisons so it vectorizes and keeps
/// `max(lo, min(hi, z))` semantics exactly (lo <= hi assumed).
#[inline(always)]
pub fn clamp(z: f64, lo: f64, hi: f64) -> f64 {
    let z = if z < hi { z } else { hi };
    if z > lo {
        z
    } else {
        lo
    }
}

/// Two `f64` side by side: on x86-64 one packed SSE2 instruction per operation (SSE2 is
/// part of x86-64; the same IEEE operations as two scalar ones, so the results are those of
/// the scalar code to the bit), a plain pair elsewhere. For work done for both directions of
/// a sub-step at once (`stage.rs`).
#[derive(Clone, Copy)]
pub(crate) struct F2(F2Repr);

impl core::fmt::Debug for F2 {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.get().fmt(f)
    }
}

#[cfg(target_arch = "x86_64")]
type F2Repr = core::arch::x86_64::__m128d;
#[cfg(not(target_arch = "x86_64"))]
type F2Repr = [f64; 2];

#[cfg(target_arch = "x86_64")]
// the blocks are needed before Rust 1.87 (rust-version is 1.80); since then SSE2 intrinsics are safe
#[allow(unused_unsafe)]
mod f2_impl {
    use super::F2;
    use core::arch::x86_64::*;
    impl F2 {
        #[inline(always)]
        pub(crate) fn new(a: f64, b: f64) -> F2 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            F2(unsafe { _mm_set_pd(b, a) })
        }
        #[inline(always)]
        pub(crate) fn splat(a: f64) -> F2 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            F2(unsafe { _mm_set1_pd(a) })
        }
        #[inline(always)]
        pub(crate) fn get(self) -> [f64; 2] {
            let mut out = [0.0; 2];
            // SAFETY: SSE2 is part of the x86-64 baseline; the unaligned store writes exactly the two
            // f64 of `out`
            unsafe { _mm_storeu_pd(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        pub(crate) fn abs(self) -> F2 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            F2(unsafe { _mm_andnot_pd(_mm_set1_pd(-0.0), self.0) })
        }
        /// Lanes where `self <= o` (bit 0: lane 0, bit 1: lane 1; false for NaN).
        #[inline(always)]
        pub(crate) fn le_bits(self, o: F2) -> u32 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            unsafe { _mm_movemask_pd(_mm_cmple_pd(self.0, o.0)) as u32 }
        }
        /// Lanes where `self > o`.
        #[inline(always)]
        pub(crate) fn gt_bits(self, o: F2) -> u32 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            unsafe { _mm_movemask_pd(_mm_cmpgt_pd(self.0, o.0)) as u32 }
        }
    }
    impl core::ops::Add for F2 {
        type Output = F2;
        #[inline(always)]
        fn add(self, o: F2) -> F2 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            F2(unsafe { _mm_add_pd(self.0, o.0) })
        }
    }
    impl core::ops::Sub for F2 {
        type Output = F2;
        #[inline(always)]
        fn sub(self, o: F2) -> F2 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            F2(unsafe { _mm_sub_pd(self.0, o.0) })
        }
    }
    impl core::ops::Mul for F2 {
        type Output = F2;
        #[inline(always)]
        fn mul(self, o: F2) -> F2 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            F2(unsafe { _mm_mul_pd(self.0, o.0) })
        }
    }
    impl core::ops::Div for F2 {
        type Output = F2;
        #[inline(always)]
        fn div(self, o: F2) -> F2 {
            // SAFETY: SSE2 is baseline on x86-64; the intrinsic touches registers only
            F2(unsafe { _mm_div_pd(self.0, o.0) })
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod f2_impl {
    use super::F2;
    impl F2 {
        #[inline(always)]
        pub(crate) fn new(a: f64, b: f64) -> F2 {
            F2([a, b])
        }
        #[inline(always)]
        pub(crate) fn splat(a: f64) -> F2 {
            F2([a, a])
        }
        #[inline(always)]
        pub(crate) fn get(self) -> [f64; 2] {
            self.0
        }
        #[inline(always)]
        pub(crate) fn abs(self) -> F2 {
            F2([super::abs(self.0[0]), super::abs(self.0[1])])
        }
        #[inline(always)]
        pub(crate) fn le_bits(self, o: F2) -> u32 {
            u32::from(self.0[0] <= o.0[0]) | (u32::from(self.0[1] <= o.0[1]) << 1)
        }
        #[inline(always)]
        pub(crate) fn gt_bits(self, o: F2) -> u32 {
            u32::from(self.0[0] > o.0[0]) | (u32::from(self.0[1] > o.0[1]) << 1)
        }
    }
    macro_rules! op {
        ($tr:ident, $f:ident, $op:tt) => {
            impl core::ops::$tr for F2 {
                type Output = F2;
                #[inline(always)]
                fn $f(self, o: F2) -> F2 {
                    F2([self.0[0] $op o.0[0], self.0[1] $op o.0[1]])
                }
            }
        };
    }
    op!(Add, add, +);
    op!(Sub, sub, -);
    op!(Mul, mul, *);
    op!(Div, div, /);
}
