//! The AVX-512 row loop of the product passes: the Sobel operator fused in
//! registers, the next vector shifted in with `valignd`.

use super::{lanes, Params};

/// One row's `q`s multiplied into `product` (`q^w` with 0/1 weights
/// `mask`), with the vertical and horizontal Sobel passes fused in
/// registers: each vector's vertical passes come from the three mapped rows
/// `a`, `b`, `c` and the next vector's are shifted in across the boundary
/// (`valignd`), so the only memory traffic is the three rows and the
/// product. AVX-512 only: the portable lanes cannot express the shift (LLVM
/// makes gathers of it). Returns `false`, having done nothing, when a buffer
/// is shorter than the pass needs (the rows are padded by one vector).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
#[allow(unsafe_code)]
pub(super) fn product_row_avx512(
    rows: [&[f32]; 3],
    product: &mut [f32],
    mask: Option<&[f32]>,
    n: usize,
    p: &Params,
) -> bool {
    use std::arch::x86_64::{
        __m512, _mm512_add_ps, _mm512_alignr_epi32, _mm512_castps_si512, _mm512_castsi512_ps,
        _mm512_cmp_ps_mask, _mm512_fmadd_ps, _mm512_loadu_ps, _mm512_mask_blend_ps, _mm512_max_ps,
        _mm512_mul_ps, _mm512_set1_ps, _mm512_setzero_ps, _mm512_sqrt_ps, _mm512_storeu_ps,
        _mm512_sub_ps, _CMP_GT_OQ,
    };
    const L: usize = 16;
    let chunks = n.div_ceil(L);
    let [a, b, c] = rows;
    if [a, b, c].iter().any(|r| r.len() < (chunks + 1) * L)
        || product.len() < chunks * L
        || mask.is_some_and(|m| m.len() < n)
    {
        return false;
    }
    // SAFETY (every load and store below): the lengths were checked above,
    // so vector `k ≤ chunks` of a row and vector `k < chunks` of the product
    // lie inside their slices; mask loads go through `lanes`.
    let load =
        |row: &[f32], k: usize| -> __m512 { unsafe { _mm512_loadu_ps(row.as_ptr().add(k * L)) } };
    let two = _mm512_set1_ps(2.0);
    let offset = _mm512_set1_ps(p.offset);
    let one = _mm512_set1_ps(1.0);
    let vertical = |k: usize| {
        let (av, bv, cv) = (load(a, k), load(b, k), load(c, k));
        (
            _mm512_fmadd_ps(two, bv, _mm512_add_ps(av, cv)),
            _mm512_sub_ps(cv, av),
        )
    };
    let shift = |next: __m512, cur: __m512, k: u8| -> __m512 {
        let (next, cur) = (_mm512_castps_si512(next), _mm512_castps_si512(cur));
        _mm512_castsi512_ps(if k == 1 {
            _mm512_alignr_epi32::<1>(next, cur)
        } else {
            _mm512_alignr_epi32::<2>(next, cur)
        })
    };
    let (mut sv, mut dv) = vertical(0);
    for k in 0..chunks {
        let (sv_next, dv_next) = vertical(k + 1);
        let gx = _mm512_sub_ps(shift(sv_next, sv, 2), sv);
        let gy = _mm512_fmadd_ps(
            two,
            shift(dv_next, dv, 1),
            _mm512_add_ps(dv, shift(dv_next, dv, 2)),
        );
        let mag2 = _mm512_fmadd_ps(gx, gx, _mm512_mul_ps(gy, gy));
        let q = _mm512_max_ps(_mm512_add_ps(_mm512_sqrt_ps(mag2), offset), one);
        // Lanes past the row, and with weight 0, take 1.
        let rest = n - k * L;
        let mut keep: u16 = if rest < L {
            (1u16 << rest) - 1
        } else {
            u16::MAX
        };
        if let Some(mask) = mask {
            let m = lanes::<L>(mask, k * L);
            let mv = unsafe { _mm512_loadu_ps(m.as_ptr()) };
            keep &= _mm512_cmp_ps_mask::<_CMP_GT_OQ>(mv, _mm512_setzero_ps());
        }
        let q = _mm512_mask_blend_ps(keep, one, q);
        let at = unsafe { product.as_mut_ptr().add(k * L) };
        unsafe { _mm512_storeu_ps(at, _mm512_mul_ps(_mm512_loadu_ps(at), q)) };
        sv = sv_next;
        dv = dv_next;
    }
    true
}
