//! Four and eight f32 lanes and the operations Kiln's kernels use (the wide BVH's box and
//! triangle tests, the light hierarchy's importances), as SSE2 (AVX2 for eight) on x86-64
//! and as plain arrays elsewhere, with the same result to the bit either way: each operation is
//! one IEEE-754 operation per lane (no fused multiply-add, no reciprocal estimate), and
//! `min`/`max` are SSE's (`a < b ? a : b`, so a NaN picks the second operand).

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// Four lanes of f32.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F4(__m128);

/// Four lanes of f32.
#[cfg(not(target_arch = "x86_64"))]
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F4([f32; 4]);

/// A lane mask: bit i set where lane i holds.
pub type Mask = u32;

/// What the triangle test needs of a row of lanes: four ([`F4`]) or eight ([`F8`]).
pub trait Lanes: Copy {
    fn splat(x: f32) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    fn min(self, o: Self) -> Self;
    fn le(self, o: Self) -> Mask;
    fn nonzero(self) -> Mask;
    fn signs(self) -> Mask;
    fn or(self, o: Self) -> Self;
}

/// Forwards a lane type's own operations to [`Lanes`].
macro_rules! lanes {
    ($t:ty) => {
        impl Lanes for $t {
            #[inline(always)]
            fn splat(x: f32) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                <$t>::add(self, o)
            }
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                <$t>::sub(self, o)
            }
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                <$t>::mul(self, o)
            }
            #[inline(always)]
            fn div(self, o: Self) -> Self {
                <$t>::div(self, o)
            }
            #[inline(always)]
            fn min(self, o: Self) -> Self {
                <$t>::min(self, o)
            }
            #[inline(always)]
            fn le(self, o: Self) -> Mask {
                <$t>::le(self, o)
            }
            #[inline(always)]
            fn nonzero(self) -> Mask {
                <$t>::nonzero(self)
            }
            #[inline(always)]
            fn signs(self) -> Mask {
                <$t>::signs(self)
            }
            #[inline(always)]
            fn or(self, o: Self) -> Self {
                <$t>::or(self, o)
            }
        }
    };
}
lanes!(F4);
#[cfg(target_arch = "x86_64")]
lanes!(F8);

#[cfg(target_arch = "x86_64")]
impl F4 {
    #[inline(always)]
    pub fn load(v: &[f32; 4]) -> F4 {
        // SAFETY: SSE2 is part of every x86-64 CPU; `v` is 16 bytes.
        F4(unsafe { _mm_loadu_ps(v.as_ptr()) })
    }
    #[inline(always)]
    pub fn splat(x: f32) -> F4 {
        // SAFETY: SSE2 is part of every x86-64 CPU.
        F4(unsafe { _mm_set1_ps(x) })
    }
    #[inline(always)]
    pub fn store(self) -> [f32; 4] {
        let mut out = [0f32; 4];
        // SAFETY: SSE2 is part of every x86-64 CPU; `out` is 16 bytes.
        unsafe { _mm_storeu_ps(out.as_mut_ptr(), self.0) };
        out
    }
    #[inline(always)]
    pub fn add(self, o: F4) -> F4 {
        // SAFETY: SSE2 is part of every x86-64 CPU.
        F4(unsafe { _mm_add_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn sub(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_sub_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn mul(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_mul_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn div(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_div_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn min(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_min_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn max(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_max_ps(self.0, o.0) })
    }
    /// Lanes where `self <= o` (false where either is NaN).
    #[inline(always)]
    pub fn le(self, o: F4) -> Mask {
        // SAFETY: as above.
        unsafe { _mm_movemask_ps(_mm_cmple_ps(self.0, o.0)) as Mask }
    }
    /// Lanes where `self != 0` (true where NaN).
    #[inline(always)]
    pub fn nonzero(self) -> Mask {
        // SAFETY: as above.
        unsafe { _mm_movemask_ps(_mm_cmpneq_ps(self.0, _mm_setzero_ps())) as Mask }
    }
    /// Lanes whose sign bit is set.
    #[inline(always)]
    pub fn signs(self) -> Mask {
        // SAFETY: as above.
        unsafe { _mm_movemask_ps(self.0) as Mask }
    }
    /// The bitwise or of the lanes of `self` and `o`.
    #[inline(always)]
    pub fn or(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_or_ps(self.0, o.0) })
    }
    /// `v` in the first two lanes, zeros in the others.
    #[inline(always)]
    pub fn load2(v: &[f32; 2]) -> F4 {
        // SAFETY: SSE2 is part of every x86-64 CPU; `v` is 8 bytes, read unaligned.
        F4(unsafe { _mm_castsi128_ps(_mm_loadl_epi64(v.as_ptr() as *const __m128i)) })
    }
    /// The square root of each lane (correctly rounded, as `f32::sqrt`).
    #[inline(always)]
    pub fn sqrt(self) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_sqrt_ps(self.0) })
    }
    /// All bits set in the lanes that hold a NaN.
    #[inline(always)]
    pub fn nan_lanes(self) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_cmpunord_ps(self.0, self.0) })
    }
    /// Each lane with its sign bit cleared, as `f32::abs`.
    #[inline(always)]
    pub fn abs(self) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), self.0) })
    }
    /// All bits set in the lanes where `self < o` (none where either is NaN).
    #[inline(always)]
    pub fn lt_lanes(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_cmplt_ps(self.0, o.0) })
    }
    /// All bits set in the lanes where `self <= o` (none where either is NaN).
    #[inline(always)]
    pub fn le_lanes(self, o: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_cmple_ps(self.0, o.0) })
    }
    /// In the lanes whose bits `self` (a mask from a comparison) sets, `a`; elsewhere `b`.
    #[inline(always)]
    pub fn select(self, a: F4, b: F4) -> F4 {
        // SAFETY: as above.
        F4(unsafe { _mm_or_ps(_mm_and_ps(self.0, a.0), _mm_andnot_ps(self.0, b.0)) })
    }
}

#[cfg(not(target_arch = "x86_64"))]
impl F4 {
    #[inline(always)]
    pub fn load(v: &[f32; 4]) -> F4 {
        F4(*v)
    }
    #[inline(always)]
    pub fn splat(x: f32) -> F4 {
        F4([x; 4])
    }
    #[inline(always)]
    pub fn store(self) -> [f32; 4] {
        self.0
    }
    #[inline(always)]
    fn zip(self, o: F4, f: impl Fn(f32, f32) -> f32) -> F4 {
        F4(std::array::from_fn(|i| f(self.0[i], o.0[i])))
    }
    #[inline(always)]
    fn bits(self, f: impl Fn(f32) -> bool) -> Mask {
        (0..4).fold(0, |m, i| m | ((f(self.0[i]) as Mask) << i))
    }
    #[inline(always)]
    pub fn add(self, o: F4) -> F4 {
        self.zip(o, |a, b| a + b)
    }
    #[inline(always)]
    pub fn sub(self, o: F4) -> F4 {
        self.zip(o, |a, b| a - b)
    }
    #[inline(always)]
    pub fn mul(self, o: F4) -> F4 {
        self.zip(o, |a, b| a * b)
    }
    #[inline(always)]
    pub fn div(self, o: F4) -> F4 {
        self.zip(o, |a, b| a / b)
    }
    #[inline(always)]
    pub fn min(self, o: F4) -> F4 {
        self.zip(o, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    pub fn max(self, o: F4) -> F4 {
        self.zip(o, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    pub fn le(self, o: F4) -> Mask {
        (0..4).fold(0, |m, i| m | (((self.0[i] <= o.0[i]) as Mask) << i))
    }
    #[inline(always)]
    pub fn nonzero(self) -> Mask {
        self.bits(|x| x != 0.0)
    }
    #[inline(always)]
    pub fn signs(self) -> Mask {
        self.bits(|x| x.is_sign_negative())
    }
    #[inline(always)]
    pub fn or(self, o: F4) -> F4 {
        self.zip(o, |a, b| f32::from_bits(a.to_bits() | b.to_bits()))
    }
    #[inline(always)]
    pub fn load2(v: &[f32; 2]) -> F4 {
        F4([v[0], v[1], 0.0, 0.0])
    }
    #[inline(always)]
    pub fn sqrt(self) -> F4 {
        F4(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    pub fn nan_lanes(self) -> F4 {
        self.mask(self, |a, _| a.is_nan())
    }
    #[inline(always)]
    pub fn abs(self) -> F4 {
        F4(self.0.map(f32::abs))
    }
    #[inline(always)]
    fn mask(self, o: F4, f: impl Fn(f32, f32) -> bool) -> F4 {
        self.zip(o, |a, b| f32::from_bits(if f(a, b) { u32::MAX } else { 0 }))
    }
    #[inline(always)]
    pub fn lt_lanes(self, o: F4) -> F4 {
        self.mask(o, |a, b| a < b)
    }
    #[inline(always)]
    pub fn le_lanes(self, o: F4) -> F4 {
        self.mask(o, |a, b| a <= b)
    }
    #[inline(always)]
    pub fn select(self, a: F4, b: F4) -> F4 {
        F4(std::array::from_fn(|i| {
            let m = self.0[i].to_bits();
            f32::from_bits((m & a.0[i].to_bits()) | (!m & b.0[i].to_bits()))
        }))
    }
}

/// Eight lanes of f32, as AVX. Its operations may run only in code compiled for AVX2 (the
/// walks' `_avx2` functions, chosen where the CPU has it); each is the same IEEE operation
/// per lane as [`F4`]'s.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F8(__m256);

#[cfg(target_arch = "x86_64")]
impl F8 {
    /// `v`, which must be 32-byte aligned (a node's rows are).
    #[inline(always)]
    pub fn load_aligned(v: &[f32; 8]) -> F8 {
        debug_assert_eq!(v.as_ptr() as usize % 32, 0, "an aligned row");
        // SAFETY: only run where the CPU has AVX2; `v` is 32 bytes, 32-byte aligned (every
        // caller's row is: Node is 64-byte aligned and its rows are 32 bytes each).
        F8(unsafe { _mm256_load_ps(v.as_ptr()) })
    }
    #[inline(always)]
    pub fn splat(x: f32) -> F8 {
        // SAFETY: only run where the CPU has AVX2.
        F8(unsafe { _mm256_set1_ps(x) })
    }
    #[inline(always)]
    pub fn store(self) -> [f32; 8] {
        let mut out = [0f32; 8];
        // SAFETY: only run where the CPU has AVX2; `out` is 32 bytes.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
        out
    }
    /// Four lanes from `lo` and four from `hi`.
    #[inline(always)]
    pub fn halves(lo: &[f32; 4], hi: &[f32; 4]) -> F8 {
        // SAFETY: only run where the CPU has AVX2; each half is 16 bytes.
        F8(unsafe { _mm256_loadu2_m128(hi.as_ptr(), lo.as_ptr()) })
    }
    #[inline(always)]
    pub fn add(self, o: F8) -> F8 {
        // SAFETY: only run where the CPU has AVX2.
        F8(unsafe { _mm256_add_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn sub(self, o: F8) -> F8 {
        // SAFETY: only run where the CPU has AVX2.
        F8(unsafe { _mm256_sub_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn div(self, o: F8) -> F8 {
        // SAFETY: as above.
        F8(unsafe { _mm256_div_ps(self.0, o.0) })
    }
    /// Lanes where `self != 0` (true where NaN, as SSE's `cmpneqps`).
    #[inline(always)]
    pub fn nonzero(self) -> Mask {
        // SAFETY: as above.
        unsafe {
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, _mm256_setzero_ps())) as Mask
        }
    }
    /// Lanes whose sign bit is set.
    #[inline(always)]
    pub fn signs(self) -> Mask {
        // SAFETY: as above.
        unsafe { _mm256_movemask_ps(self.0) as Mask }
    }
    #[inline(always)]
    pub fn or(self, o: F8) -> F8 {
        // SAFETY: as above.
        F8(unsafe { _mm256_or_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn mul(self, o: F8) -> F8 {
        // SAFETY: as above.
        F8(unsafe { _mm256_mul_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn min(self, o: F8) -> F8 {
        // SAFETY: as above.
        F8(unsafe { _mm256_min_ps(self.0, o.0) })
    }
    #[inline(always)]
    pub fn max(self, o: F8) -> F8 {
        // SAFETY: as above.
        F8(unsafe { _mm256_max_ps(self.0, o.0) })
    }
    /// Lanes where `self <= o` (false where either is NaN, as SSE's `cmpleps`).
    #[inline(always)]
    pub fn le(self, o: F8) -> Mask {
        // SAFETY: as above.
        unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0)) as Mask }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lanes do what one f32 operation per lane does, NaNs and signed zeros included.
    #[test]
    fn each_lane_is_one_ieee_operation() {
        let a = [1.5f32, -0.0, f32::NAN, 3.0e-39];
        let b = [f32::NAN, 0.0, 2.0, -7.25];
        let (x, y) = (F4::load(&a), F4::load(&b));
        let bits = |v: [f32; 4]| v.map(f32::to_bits);
        for (got, want) in [
            (x.add(y).store(), std::array::from_fn(|i| a[i] + b[i])),
            (x.sub(y).store(), std::array::from_fn(|i| a[i] - b[i])),
            (x.mul(y).store(), std::array::from_fn(|i| a[i] * b[i])),
            (x.div(y).store(), std::array::from_fn(|i| a[i] / b[i])),
        ] {
            let want: [f32; 4] = want;
            for i in 0..4 {
                assert!(
                    got[i].to_bits() == want[i].to_bits() || (got[i].is_nan() && want[i].is_nan())
                );
            }
        }
        assert_eq!(
            bits(x.min(y).store()),
            bits([b[0], 0.0, 2.0, -7.25]),
            "a NaN picks the second operand"
        );
        assert_eq!(bits(x.max(y).store())[1], 0.0f32.to_bits());
        assert_eq!(x.le(y), 0b0010);
        assert_eq!(x.signs(), 0b0010);
        assert_eq!(x.nonzero(), 0b1101);
        let c = [4.0f32, -0.0, f32::NAN, -f32::INFINITY];
        let z = F4::load(&c);
        for (i, x) in c.into_iter().enumerate() {
            let (sq, ab) = (z.sqrt().store()[i], z.abs().store()[i]);
            assert!(sq.to_bits() == x.sqrt().to_bits() || (sq.is_nan() && x.sqrt().is_nan()));
            assert_eq!(ab.to_bits(), x.abs().to_bits());
        }
        // NaN compares false; the masks pick whole lanes.
        let lt = x.lt_lanes(y).select(F4::splat(1.0), F4::splat(2.0)).store();
        assert_eq!(lt, [2.0, 2.0, 2.0, 2.0]);
        let le = x.le_lanes(y).select(x, y).store().map(f32::to_bits);
        assert_eq!(le, [b[0], -0.0, b[2], b[3]].map(f32::to_bits));
        assert_eq!(y.lt_lanes(x).select(y, x).store()[3], -7.25);
        let nan = x.nan_lanes().select(F4::splat(1.0), F4::splat(0.0)).store();
        assert_eq!(nan, [0.0, 0.0, 1.0, 0.0]);
        assert_eq!(F4::load2(&[3.0, -1.0]).store(), [3.0, -1.0, 0.0, 0.0]);
    }
}
