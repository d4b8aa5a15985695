//! Lane vectors for `cpu::lanes`: N floats, N integers and an N-lane mask, over AVX2 (eight
//! lanes) or AVX-512 (sixteen), with the operations the lanes' path loop takes. Each is one
//! instruction, nothing fused, IEEE-exact where the scalar tracer is (add, mul, div, sqrt;
//! min and max as x86's minps and maxps), so both widths compute each lane bit for bit as
//! the scalar tracer does.
//!
//! A value exists only where its instruction set does: the one way to make one is through
//! an `Isa` token (`Avx2::new`, `Avx512::new` check the CPU), so the operations on values are
//! safe. They are `#[inline(always)]`: they compile into the caller that enables the
//! instruction set (`lanes::Lanes::trace`'s entry points), the pattern of `pulp` and of
//! `std::arch`'s own docs ("Dynamic CPU feature detection").

use std::arch::x86_64::*;
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Sub};

/// The most lanes of any width: the size of the arrays lanes are loaded from and stored to.
pub const MAX_LANES: usize = 16;

/// Floats as arrays of `MAX_LANES`, of which a width reads its first N.
pub type Row = [f32; MAX_LANES];

/// An instruction set's lanes. The methods are unsafe to call where the CPU lacks it; the
/// safe types below call them only from values an `Isa` token made.
///
/// # Safety
/// An implementation's `new` returns a token only where the CPU has what its methods use.
pub unsafe trait Isa: Copy + 'static {
    /// Lanes per vector.
    const N: usize;
    type F: Copy;
    type I: Copy;
    type M: Copy;
    /// The token where the CPU has the instruction set.
    fn new() -> Option<Self>;
    unsafe fn splat(x: f32) -> Self::F;
    unsafe fn load(a: &Row) -> Self::F;
    unsafe fn store(a: Self::F, out: &mut Row);
    unsafe fn add(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn sub(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn mul(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn div(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn sqrt(a: Self::F) -> Self::F;
    unsafe fn min(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn max(a: Self::F, b: Self::F) -> Self::F;
    /// The sign bit flipped (`xor -0.0`) and cleared (`andnot -0.0`).
    unsafe fn neg(a: Self::F) -> Self::F;
    unsafe fn abs(a: Self::F) -> Self::F;
    /// Compare with one of `_CMP_*`'s predicates.
    unsafe fn cmp<const P: i32>(a: Self::F, b: Self::F) -> Self::M;
    /// `a`, replaced by `b` in the lanes of `m`.
    unsafe fn blend(a: Self::F, b: Self::F, m: Self::M) -> Self::F;
    /// `a` in the lanes of `m`, +0.0 elsewhere.
    unsafe fn keep(a: Self::F, m: Self::M) -> Self::F;
    /// Each lane's entry `idx` (0 to N − 1) of a table.
    unsafe fn pick(t: &Row, idx: Self::I) -> Self::F;
    unsafe fn to_bits(a: Self::F) -> Self::I;
    unsafe fn from_bits(a: Self::I) -> Self::F;
    /// Truncated toward zero, and back.
    unsafe fn truncate(a: Self::F) -> Self::I;
    /// Rounded toward zero, as a float.
    unsafe fn trunc(a: Self::F) -> Self::F;
    /// Truncated toward zero as an unsigned integer, for lanes in [0, 2^32).
    unsafe fn truncate_unsigned(a: Self::F) -> Self::I;
    unsafe fn to_float(a: Self::I) -> Self::F;
    unsafe fn isplat(x: i32) -> Self::I;
    unsafe fn iload(a: &[i32; MAX_LANES]) -> Self::I;
    /// The low 32 bits of the product (wrapping).
    unsafe fn imul(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn ior(a: Self::I, b: Self::I) -> Self::I;
    /// Shifted right (logical) by k bits, and by each lane's own count.
    unsafe fn ishr(a: Self::I, k: i32) -> Self::I;
    unsafe fn ishrv(a: Self::I, b: Self::I) -> Self::I;
    /// Each lane's bits reversed (`u32::reverse_bits`): each byte's by two table lookups of
    /// its nibbles, then the bytes'.
    unsafe fn reverse_bits(a: Self::I) -> Self::I;
    unsafe fn istore(a: Self::I, out: &mut [i32; MAX_LANES]);
    unsafe fn iadd(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn isub(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn iand(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn ixor(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn imax(a: Self::I, b: Self::I) -> Self::I;
    /// The smaller, as unsigned integers.
    unsafe fn iminu(a: Self::I, b: Self::I) -> Self::I;
    /// Each lane's word `idx` of `base` (every index within it: the caller's promise).
    unsafe fn gather(base: *const i32, idx: Self::I) -> Self::I;
    /// Shifted left by 30 bits.
    unsafe fn shl30(a: Self::I) -> Self::I;
    unsafe fn ieq(a: Self::I, b: Self::I) -> Self::M;
    unsafe fn igt(a: Self::I, b: Self::I) -> Self::M;
    unsafe fn iblend(a: Self::I, b: Self::I, m: Self::M) -> Self::I;
    /// All bits set where `bits`' bit k is, in lane k.
    unsafe fn mask(bits: u32) -> Self::M;
    unsafe fn bits(m: Self::M) -> u32;
    unsafe fn mand(a: Self::M, b: Self::M) -> Self::M;
    unsafe fn mor(a: Self::M, b: Self::M) -> Self::M;
    unsafe fn mxor(a: Self::M, b: Self::M) -> Self::M;
    /// `!a & b`.
    unsafe fn mandnot(a: Self::M, b: Self::M) -> Self::M;
}

/// Eight lanes: AVX and AVX2.
#[derive(Clone, Copy)]
pub struct Avx2(());

/// Sixteen lanes: AVX-512 F, DQ and BW.
#[derive(Clone, Copy)]
pub struct Avx512(());

/// `reverse_bits`' tables, for two 128-bit halves: a nibble's bits reversed and moved to the
/// byte's high half, a nibble's bits reversed, and the bytes of each 32-bit lane reversed.
const REVERSE: [[i8; 32]; 3] = {
    const R: [i8; 16] = [0, 8, 4, 12, 2, 10, 6, 14, 1, 9, 5, 13, 3, 11, 7, 15];
    let mut t = [[0i8; 32]; 3];
    let mut i = 0;
    while i < 32 {
        t[0][i] = ((R[i % 16] as u8) << 4) as i8;
        t[1][i] = R[i % 16];
        t[2][i] = ((i % 16) / 4 * 4 + 3 - i % 4) as i8;
        i += 1;
    }
    t
};

/// `_mm256_movemask_ps`'s bits of lanes 0..N.
const ALL8: u32 = 0xff;

// SAFETY: `new` checks AVX and AVX2, all the methods use.
unsafe impl Isa for Avx2 {
    const N: usize = 8;
    type F = __m256;
    type I = __m256i;
    type M = __m256;
    fn new() -> Option<Self> {
        (is_x86_feature_detected!("avx") && is_x86_feature_detected!("avx2")).then_some(Avx2(()))
    }
    #[inline(always)]
    unsafe fn splat(x: f32) -> __m256 {
        unsafe { _mm256_set1_ps(x) }
    }
    #[inline(always)]
    unsafe fn load(a: &Row) -> __m256 {
        unsafe { _mm256_loadu_ps(a.as_ptr()) }
    }
    #[inline(always)]
    unsafe fn store(a: __m256, out: &mut Row) {
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), a) }
    }
    #[inline(always)]
    unsafe fn add(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_add_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn sub(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_sub_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn mul(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_mul_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn div(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_div_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn sqrt(a: __m256) -> __m256 {
        unsafe { _mm256_sqrt_ps(a) }
    }
    #[inline(always)]
    unsafe fn min(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_min_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn max(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_max_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn neg(a: __m256) -> __m256 {
        unsafe { _mm256_xor_ps(a, _mm256_set1_ps(-0.0)) }
    }
    #[inline(always)]
    unsafe fn abs(a: __m256) -> __m256 {
        unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), a) }
    }
    #[inline(always)]
    unsafe fn cmp<const P: i32>(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_cmp_ps::<P>(a, b) }
    }
    #[inline(always)]
    unsafe fn blend(a: __m256, b: __m256, m: __m256) -> __m256 {
        unsafe { _mm256_blendv_ps(a, b, m) }
    }
    #[inline(always)]
    unsafe fn keep(a: __m256, m: __m256) -> __m256 {
        unsafe { _mm256_and_ps(a, m) }
    }
    #[inline(always)]
    unsafe fn pick(t: &Row, idx: __m256i) -> __m256 {
        unsafe { _mm256_permutevar8x32_ps(<Self as Isa>::load(t), idx) }
    }
    #[inline(always)]
    unsafe fn to_bits(a: __m256) -> __m256i {
        unsafe { _mm256_castps_si256(a) }
    }
    #[inline(always)]
    unsafe fn from_bits(a: __m256i) -> __m256 {
        unsafe { _mm256_castsi256_ps(a) }
    }
    #[inline(always)]
    unsafe fn truncate(a: __m256) -> __m256i {
        unsafe { _mm256_cvttps_epi32(a) }
    }
    #[inline(always)]
    unsafe fn trunc(a: __m256) -> __m256 {
        unsafe { _mm256_round_ps::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(a) }
    }
    #[inline(always)]
    unsafe fn truncate_unsigned(a: __m256) -> __m256i {
        // AVX2 converts to signed integers only: a lane of 2^31 or more is converted less
        // 2^31 (exact: both are multiples of its spacing, at least 256) and the bit set.
        unsafe {
            let half = _mm256_set1_ps(2147483648.0);
            let big = _mm256_cmp_ps::<_CMP_GE_OQ>(a, half);
            let low = _mm256_cvttps_epi32(_mm256_sub_ps(a, _mm256_and_ps(half, big)));
            let top = _mm256_and_si256(_mm256_castps_si256(big), _mm256_set1_epi32(i32::MIN));
            _mm256_xor_si256(low, top)
        }
    }
    #[inline(always)]
    unsafe fn to_float(a: __m256i) -> __m256 {
        unsafe { _mm256_cvtepi32_ps(a) }
    }
    #[inline(always)]
    unsafe fn isplat(x: i32) -> __m256i {
        unsafe { _mm256_set1_epi32(x) }
    }
    #[inline(always)]
    unsafe fn iload(a: &[i32; MAX_LANES]) -> __m256i {
        unsafe { _mm256_loadu_si256(a.as_ptr() as *const __m256i) }
    }
    #[inline(always)]
    unsafe fn imul(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_mullo_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn ior(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_or_si256(a, b) }
    }
    #[inline(always)]
    unsafe fn ishr(a: __m256i, k: i32) -> __m256i {
        unsafe { _mm256_srl_epi32(a, _mm_cvtsi32_si128(k)) }
    }
    #[inline(always)]
    unsafe fn ishrv(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_srlv_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn reverse_bits(a: __m256i) -> __m256i {
        unsafe {
            let t = REVERSE.as_ptr() as *const __m256i;
            let (low, high, swap) = (
                _mm256_loadu_si256(t),
                _mm256_loadu_si256(t.add(1)),
                _mm256_loadu_si256(t.add(2)),
            );
            let nibbles = _mm256_set1_epi8(0x0f);
            let lo = _mm256_and_si256(a, nibbles);
            let hi = _mm256_and_si256(_mm256_srli_epi16::<4>(a), nibbles);
            let bytes =
                _mm256_or_si256(_mm256_shuffle_epi8(low, lo), _mm256_shuffle_epi8(high, hi));
            _mm256_shuffle_epi8(bytes, swap)
        }
    }
    #[inline(always)]
    unsafe fn istore(a: __m256i, out: &mut [i32; MAX_LANES]) {
        unsafe { _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, a) }
    }
    #[inline(always)]
    unsafe fn iadd(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_add_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn isub(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_sub_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn iand(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_and_si256(a, b) }
    }
    #[inline(always)]
    unsafe fn ixor(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_xor_si256(a, b) }
    }
    #[inline(always)]
    unsafe fn imax(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_max_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn iminu(a: __m256i, b: __m256i) -> __m256i {
        unsafe { _mm256_min_epu32(a, b) }
    }
    #[inline(always)]
    unsafe fn gather(base: *const i32, idx: __m256i) -> __m256i {
        unsafe { _mm256_i32gather_epi32::<4>(base, idx) }
    }
    #[inline(always)]
    unsafe fn shl30(a: __m256i) -> __m256i {
        unsafe { _mm256_slli_epi32::<30>(a) }
    }
    #[inline(always)]
    unsafe fn ieq(a: __m256i, b: __m256i) -> __m256 {
        unsafe { _mm256_castsi256_ps(_mm256_cmpeq_epi32(a, b)) }
    }
    #[inline(always)]
    unsafe fn igt(a: __m256i, b: __m256i) -> __m256 {
        unsafe { _mm256_castsi256_ps(_mm256_cmpgt_epi32(a, b)) }
    }
    #[inline(always)]
    unsafe fn iblend(a: __m256i, b: __m256i, m: __m256) -> __m256i {
        unsafe { Self::to_bits(_mm256_blendv_ps(Self::from_bits(a), Self::from_bits(b), m)) }
    }
    #[inline(always)]
    unsafe fn mask(bits: u32) -> __m256 {
        unsafe {
            let lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            let m = _mm256_and_si256(_mm256_set1_epi32(bits as i32), lanes);
            _mm256_castsi256_ps(_mm256_cmpeq_epi32(m, lanes))
        }
    }
    #[inline(always)]
    unsafe fn bits(m: __m256) -> u32 {
        unsafe { _mm256_movemask_ps(m) as u32 & ALL8 }
    }
    #[inline(always)]
    unsafe fn mand(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_and_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn mor(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_or_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn mxor(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_xor_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn mandnot(a: __m256, b: __m256) -> __m256 {
        unsafe { _mm256_andnot_ps(a, b) }
    }
}

// SAFETY: `new` checks AVX-512 F, DQ and BW, all the methods use.
unsafe impl Isa for Avx512 {
    const N: usize = 16;
    type F = __m512;
    type I = __m512i;
    type M = __mmask16;
    fn new() -> Option<Self> {
        (is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512dq")
            && is_x86_feature_detected!("avx512bw"))
        .then_some(Avx512(()))
    }
    #[inline(always)]
    unsafe fn splat(x: f32) -> __m512 {
        unsafe { _mm512_set1_ps(x) }
    }
    #[inline(always)]
    unsafe fn load(a: &Row) -> __m512 {
        unsafe { _mm512_loadu_ps(a.as_ptr()) }
    }
    #[inline(always)]
    unsafe fn store(a: __m512, out: &mut Row) {
        unsafe { _mm512_storeu_ps(out.as_mut_ptr(), a) }
    }
    #[inline(always)]
    unsafe fn add(a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_add_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn sub(a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_sub_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn mul(a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_mul_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn div(a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_div_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn sqrt(a: __m512) -> __m512 {
        unsafe { _mm512_sqrt_ps(a) }
    }
    #[inline(always)]
    unsafe fn min(a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_min_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn max(a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_max_ps(a, b) }
    }
    #[inline(always)]
    unsafe fn neg(a: __m512) -> __m512 {
        unsafe { _mm512_xor_ps(a, _mm512_set1_ps(-0.0)) }
    }
    #[inline(always)]
    unsafe fn abs(a: __m512) -> __m512 {
        unsafe { _mm512_andnot_ps(_mm512_set1_ps(-0.0), a) }
    }
    #[inline(always)]
    unsafe fn cmp<const P: i32>(a: __m512, b: __m512) -> __mmask16 {
        unsafe { _mm512_cmp_ps_mask::<P>(a, b) }
    }
    #[inline(always)]
    unsafe fn blend(a: __m512, b: __m512, m: __mmask16) -> __m512 {
        unsafe { _mm512_mask_blend_ps(m, a, b) }
    }
    #[inline(always)]
    unsafe fn keep(a: __m512, m: __mmask16) -> __m512 {
        unsafe { _mm512_maskz_mov_ps(m, a) }
    }
    #[inline(always)]
    unsafe fn pick(t: &Row, idx: __m512i) -> __m512 {
        unsafe { _mm512_permutexvar_ps(idx, <Self as Isa>::load(t)) }
    }
    #[inline(always)]
    unsafe fn to_bits(a: __m512) -> __m512i {
        unsafe { _mm512_castps_si512(a) }
    }
    #[inline(always)]
    unsafe fn from_bits(a: __m512i) -> __m512 {
        unsafe { _mm512_castsi512_ps(a) }
    }
    #[inline(always)]
    unsafe fn truncate(a: __m512) -> __m512i {
        unsafe { _mm512_cvttps_epi32(a) }
    }
    #[inline(always)]
    unsafe fn trunc(a: __m512) -> __m512 {
        unsafe { _mm512_roundscale_ps::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(a) }
    }
    #[inline(always)]
    unsafe fn truncate_unsigned(a: __m512) -> __m512i {
        unsafe { _mm512_cvttps_epu32(a) }
    }
    #[inline(always)]
    unsafe fn to_float(a: __m512i) -> __m512 {
        unsafe { _mm512_cvtepi32_ps(a) }
    }
    #[inline(always)]
    unsafe fn isplat(x: i32) -> __m512i {
        unsafe { _mm512_set1_epi32(x) }
    }
    #[inline(always)]
    unsafe fn iload(a: &[i32; MAX_LANES]) -> __m512i {
        unsafe { _mm512_loadu_si512(a.as_ptr() as *const __m512i) }
    }
    #[inline(always)]
    unsafe fn imul(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_mullo_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn ior(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_or_si512(a, b) }
    }
    #[inline(always)]
    unsafe fn ishr(a: __m512i, k: i32) -> __m512i {
        unsafe { _mm512_srl_epi32(a, _mm_cvtsi32_si128(k)) }
    }
    #[inline(always)]
    unsafe fn ishrv(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_srlv_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn reverse_bits(a: __m512i) -> __m512i {
        unsafe {
            let t = REVERSE.as_ptr() as *const __m256i;
            let (low, high, swap) = (
                _mm512_broadcast_i64x4(_mm256_loadu_si256(t)),
                _mm512_broadcast_i64x4(_mm256_loadu_si256(t.add(1))),
                _mm512_broadcast_i64x4(_mm256_loadu_si256(t.add(2))),
            );
            let nibbles = _mm512_set1_epi8(0x0f);
            let lo = _mm512_and_si512(a, nibbles);
            let hi = _mm512_and_si512(_mm512_srli_epi16::<4>(a), nibbles);
            let bytes =
                _mm512_or_si512(_mm512_shuffle_epi8(low, lo), _mm512_shuffle_epi8(high, hi));
            _mm512_shuffle_epi8(bytes, swap)
        }
    }
    #[inline(always)]
    unsafe fn istore(a: __m512i, out: &mut [i32; MAX_LANES]) {
        unsafe { _mm512_storeu_si512(out.as_mut_ptr() as *mut __m512i, a) }
    }
    #[inline(always)]
    unsafe fn iadd(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_add_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn isub(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_sub_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn iand(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_and_si512(a, b) }
    }
    #[inline(always)]
    unsafe fn ixor(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_xor_si512(a, b) }
    }
    #[inline(always)]
    unsafe fn imax(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_max_epi32(a, b) }
    }
    #[inline(always)]
    unsafe fn iminu(a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_min_epu32(a, b) }
    }
    #[inline(always)]
    unsafe fn gather(base: *const i32, idx: __m512i) -> __m512i {
        unsafe { _mm512_i32gather_epi32::<4>(idx, base) }
    }
    #[inline(always)]
    unsafe fn shl30(a: __m512i) -> __m512i {
        unsafe { _mm512_slli_epi32::<30>(a) }
    }
    #[inline(always)]
    unsafe fn ieq(a: __m512i, b: __m512i) -> __mmask16 {
        unsafe { _mm512_cmpeq_epi32_mask(a, b) }
    }
    #[inline(always)]
    unsafe fn igt(a: __m512i, b: __m512i) -> __mmask16 {
        unsafe { _mm512_cmpgt_epi32_mask(a, b) }
    }
    #[inline(always)]
    unsafe fn iblend(a: __m512i, b: __m512i, m: __mmask16) -> __m512i {
        unsafe { _mm512_mask_blend_epi32(m, a, b) }
    }
    #[inline(always)]
    unsafe fn mask(bits: u32) -> __mmask16 {
        bits as __mmask16
    }
    #[inline(always)]
    unsafe fn bits(m: __mmask16) -> u32 {
        m as u32
    }
    #[inline(always)]
    unsafe fn mand(a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }
    #[inline(always)]
    unsafe fn mor(a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }
    #[inline(always)]
    unsafe fn mxor(a: __mmask16, b: __mmask16) -> __mmask16 {
        a ^ b
    }
    #[inline(always)]
    unsafe fn mandnot(a: __mmask16, b: __mmask16) -> __mmask16 {
        !a & b
    }
}

/// N floats.
pub struct F<S: Isa>(S::F);
/// N 32-bit integers.
pub struct I<S: Isa>(S::I);
/// N lanes' flags.
pub struct M<S: Isa>(S::M);

macro_rules! copy {
    ($($t:ident),*) => {$(
        impl<S: Isa> Clone for $t<S> {
            #[inline(always)]
            fn clone(&self) -> Self {
                *self
            }
        }
        impl<S: Isa> Copy for $t<S> {}
    )*};
}
copy!(F, I, M);

/// A safe operation on values: they exist only where the token that made them checked the
/// CPU (`Isa::new`).
macro_rules! op {
    ($t:ident, $tr:ident, $f:ident, $isa:ident) => {
        impl<S: Isa> $tr for $t<S> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, b: Self) -> Self {
                // SAFETY: `self` exists, so the CPU has `S` (see the macro).
                $t(unsafe { S::$isa(self.0, b.0) })
            }
        }
    };
}
op!(F, Add, add, add);
op!(F, Sub, sub, sub);
op!(F, Mul, mul, mul);
op!(F, Div, div, div);
op!(I, Add, add, iadd);
op!(I, Mul, mul, imul);
op!(I, BitOr, bitor, ior);
op!(I, BitXor, bitxor, ixor);
op!(I, Sub, sub, isub);
op!(M, BitAnd, bitand, mand);
op!(M, BitOr, bitor, mor);

impl<S: Isa> Neg for F<S> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        // SAFETY: as in `op!`.
        F(unsafe { S::neg(self.0) })
    }
}

impl<S: Isa> Not for M<S> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        // SAFETY: as in `op!`.
        M(unsafe { S::mandnot(self.0, S::mask(u32::MAX)) })
    }
}

/// What a token makes: constants, loads, masks. (SAFETY, for every method: the token
/// exists, so the CPU has `S`.)
pub trait Make: Isa {
    #[inline(always)]
    fn splat(self, x: f32) -> F<Self> {
        F(unsafe { <Self as Isa>::splat(x) })
    }
    #[inline(always)]
    fn zero(self) -> F<Self> {
        self.splat(0.0)
    }
    #[inline(always)]
    fn load(self, a: &Row) -> F<Self> {
        F(unsafe { <Self as Isa>::load(a) })
    }
    #[inline(always)]
    fn int(self, x: i32) -> I<Self> {
        I(unsafe { <Self as Isa>::isplat(x) })
    }
    /// An unsigned integer in every lane (its bits).
    #[inline(always)]
    fn uint(self, x: u32) -> I<Self> {
        self.int(x as i32)
    }
    #[inline(always)]
    fn ints(self, a: &[i32; MAX_LANES]) -> I<Self> {
        I(unsafe { <Self as Isa>::iload(a) })
    }
    /// Lane k's flag set where bit k of `bits` is.
    #[inline(always)]
    fn mask(self, bits: u32) -> M<Self> {
        M(unsafe { <Self as Isa>::mask(bits) })
    }
}
impl<S: Isa> Make for S {}

// SAFETY, in the methods below: as in `op!`.
impl<S: Isa> F<S> {
    #[inline(always)]
    pub fn sqrt(self) -> Self {
        F(unsafe { S::sqrt(self.0) })
    }
    /// x86's minps: `b` where either is NaN (f32::min's order of operands in glam).
    #[inline(always)]
    pub fn min(self, b: Self) -> Self {
        F(unsafe { S::min(self.0, b.0) })
    }
    #[inline(always)]
    pub fn max(self, b: Self) -> Self {
        F(unsafe { S::max(self.0, b.0) })
    }
    #[inline(always)]
    pub fn abs(self) -> Self {
        F(unsafe { S::abs(self.0) })
    }
    #[inline(always)]
    pub fn cmp<const P: i32>(self, b: Self) -> M<S> {
        M(unsafe { S::cmp::<P>(self.0, b.0) })
    }
    #[inline(always)]
    pub fn lt(self, b: Self) -> M<S> {
        self.cmp::<_CMP_LT_OQ>(b)
    }
    #[inline(always)]
    pub fn gt(self, b: Self) -> M<S> {
        self.cmp::<_CMP_GT_OQ>(b)
    }
    #[inline(always)]
    pub fn le(self, b: Self) -> M<S> {
        self.cmp::<_CMP_LE_OQ>(b)
    }
    #[inline(always)]
    pub fn ge(self, b: Self) -> M<S> {
        self.cmp::<_CMP_GE_OQ>(b)
    }
    /// `self`, replaced by `b` in the lanes of `m` (`_mm256_blendv_ps(self, b, m)`).
    #[inline(always)]
    pub fn blend(self, b: Self, m: M<S>) -> Self {
        F(unsafe { S::blend(self.0, b.0, m.0) })
    }
    /// `self` in the lanes of `m`, +0.0 elsewhere.
    #[inline(always)]
    pub fn keep(self, m: M<S>) -> Self {
        F(unsafe { S::keep(self.0, m.0) })
    }
    #[inline(always)]
    pub fn trunc(self) -> Self {
        F(unsafe { S::trunc(self.0) })
    }
    #[inline(always)]
    pub fn truncate_unsigned(self) -> I<S> {
        I(unsafe { S::truncate_unsigned(self.0) })
    }
    #[inline(always)]
    pub fn to_bits(self) -> I<S> {
        I(unsafe { S::to_bits(self.0) })
    }
    #[inline(always)]
    pub fn truncate(self) -> I<S> {
        I(unsafe { S::truncate(self.0) })
    }
    #[inline(always)]
    pub fn store(self, out: &mut Row) {
        unsafe { S::store(self.0, out) }
    }
    /// Each lane's entry `idx` of table `t`.
    #[inline(always)]
    pub fn pick(t: &Row, idx: I<S>) -> Self {
        F(unsafe { S::pick(t, idx.0) })
    }
}

impl<S: Isa> I<S> {
    #[inline(always)]
    pub fn and(self, b: Self) -> Self {
        I(unsafe { S::iand(self.0, b.0) })
    }
    #[inline(always)]
    pub fn xor(self, b: Self) -> Self {
        I(unsafe { S::ixor(self.0, b.0) })
    }
    #[inline(always)]
    pub fn max(self, b: Self) -> Self {
        I(unsafe { S::imax(self.0, b.0) })
    }
    /// Shifted right (logical) by k bits.
    #[inline(always)]
    pub fn shr(self, k: i32) -> Self {
        I(unsafe { S::ishr(self.0, k) })
    }
    /// Shifted right (logical) by each lane's count in `b`.
    #[inline(always)]
    pub fn shr_each(self, b: Self) -> Self {
        I(unsafe { S::ishrv(self.0, b.0) })
    }
    /// Each lane's word `idx` of `t` (an index past its end, as unsigned, reads its last word).
    #[inline(always)]
    pub fn gather(t: &[u32], idx: Self) -> Self {
        assert!(!t.is_empty() && t.len() <= i32::MAX as usize);
        // SAFETY: `idx` exists, so the CPU has `S`; every index is clamped into `t`.
        unsafe {
            let last = S::isplat(t.len() as i32 - 1);
            I(S::gather(t.as_ptr().cast(), S::iminu(idx.0, last)))
        }
    }
    /// Each lane's word `idx` from `base`.
    ///
    /// # Safety
    /// Every lane's index must point to an initialized word of the allocation `base` is in.
    #[inline(always)]
    pub unsafe fn gather_from(base: *const u32, idx: Self) -> Self {
        // SAFETY: `idx` exists, so the CPU has `S`; the caller's promise for the rest.
        I(unsafe { S::gather(base.cast(), idx.0) })
    }
    #[inline(always)]
    pub fn reverse_bits(self) -> Self {
        I(unsafe { S::reverse_bits(self.0) })
    }
    #[inline(always)]
    pub fn shl30(self) -> Self {
        I(unsafe { S::shl30(self.0) })
    }
    #[inline(always)]
    pub fn eq(self, b: Self) -> M<S> {
        M(unsafe { S::ieq(self.0, b.0) })
    }
    #[inline(always)]
    pub fn gt(self, b: Self) -> M<S> {
        M(unsafe { S::igt(self.0, b.0) })
    }
    #[inline(always)]
    pub fn blend(self, b: Self, m: M<S>) -> Self {
        I(unsafe { S::iblend(self.0, b.0, m.0) })
    }
    /// Each lane plus one in the lanes of `m`.
    #[inline(always)]
    pub fn count(self, m: M<S>) -> Self {
        let one = unsafe { S::isplat(1) };
        I(unsafe { S::iblend(self.0, S::iadd(self.0, one), m.0) })
    }
    #[inline(always)]
    pub fn to_float(self) -> F<S> {
        F(unsafe { S::to_float(self.0) })
    }
    #[inline(always)]
    pub fn float_of_bits(self) -> F<S> {
        F(unsafe { S::from_bits(self.0) })
    }
    #[inline(always)]
    pub fn store(self, out: &mut [i32; MAX_LANES]) {
        unsafe { S::istore(self.0, out) }
    }
}

impl<S: Isa> M<S> {
    /// Bit k set where lane k's flag is.
    #[inline(always)]
    pub fn bits(self) -> u32 {
        unsafe { S::bits(self.0) }
    }
    #[inline(always)]
    pub fn any(self) -> bool {
        self.bits() != 0
    }
    #[inline(always)]
    pub fn xor(self, b: Self) -> Self {
        M(unsafe { S::mxor(self.0, b.0) })
    }
    /// `self` without the lanes of `b` (`self & !b`).
    #[inline(always)]
    pub fn without(self, b: Self) -> Self {
        M(unsafe { S::mandnot(b.0, self.0) })
    }
}

/// Lanes of a 3-vector, by component.
pub type V3<S> = [F<S>; 3];

/// glam's Vec3A dot in lanes: (x·x′ + y·y′) + z·z′.
#[inline(always)]
pub fn dot<S: Isa>(a: V3<S>, b: V3<S>) -> F<S> {
    (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2]
}

/// A 3-vector's lanes, as rows by component.
#[inline(always)]
pub fn rows<S: Isa>(v: V3<S>) -> [Row; 3] {
    let mut out = [[0.0; MAX_LANES]; 3];
    for (c, row) in out.iter_mut().enumerate() {
        v[c].store(row);
    }
    out
}

/// The lanes whose bits are set in `bits`, lowest first.
#[inline(always)]
pub fn lanes_of(mut bits: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        let k = bits.trailing_zeros();
        bits &= bits.wrapping_sub(1);
        (k < 32).then_some(k as usize)
    })
}

/// The textbook cross product, as glam computes it.
#[inline(always)]
pub fn cross<S: Isa>(a: V3<S>, c: V3<S>) -> V3<S> {
    [
        a[1] * c[2] - a[2] * c[1],
        a[2] * c[0] - a[0] * c[2],
        a[0] * c[1] - a[1] * c[0],
    ]
}

/// glam's `normalize`: v / |v|.
#[inline(always)]
pub fn normalize<S: Isa>(v: V3<S>) -> V3<S> {
    let root = dot(v, v).sqrt();
    [v[0] / root, v[1] / root, v[2] / root]
}

/// `sampling::normalize_or`: v / |v|, or `fallback` where |v|² < 10⁻¹².
#[inline(always)]
pub fn normalize_or<S: Isa>(s: S, v: V3<S>, fallback: V3<S>) -> V3<S> {
    let l2 = dot(v, v);
    let short = l2.lt(s.splat(1e-12));
    let root = l2.sqrt();
    [
        (v[0] / root).blend(fallback[0], short),
        (v[1] / root).blend(fallback[1], short),
        (v[2] / root).blend(fallback[2], short),
    ]
}
