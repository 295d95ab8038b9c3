//! Lane vectors: `L` records of the same model stepped in lockstep, one value per record in
//! each `[f64; L]`, and the matrix products they need (no allocation, no_std).
//!
//! Why: one record's step is a string of matrix-vector products whose every matrix entry is
//! loaded for one multiply; `L` records stepped together load it once for `L` multiplies, and
//! the loops over lanes carry no reduction, so they vectorize. Every lane is summed in the same
//! order whatever `L` is, so a record gives the same bits alone (`L = 1`) or in a batch.

/// One value per record of a batch stepped in lockstep.
pub type Lanes<const L: usize> = [f64; L];

/// A slice of `f64` as one-lane vectors (one record alone).
#[inline(always)]
pub fn one_lane(s: &[f64]) -> &[Lanes<1>] {
    // SAFETY: `[f64; 1]` has the size, alignment and validity of `f64`, so `s.len()` of them
    // span exactly the memory of `s`, borrowed for the same lifetime.
    unsafe { core::slice::from_raw_parts(s.as_ptr().cast::<Lanes<1>>(), s.len()) }
}

/// A mutable slice of `f64` as one-lane vectors (one record alone).
#[inline(always)]
pub fn one_lane_mut(s: &mut [f64]) -> &mut [Lanes<1>] {
    // SAFETY: as in `one_lane`; the exclusive borrow of `s` passes to the result.
    unsafe { core::slice::from_raw_parts_mut(s.as_mut_ptr().cast::<Lanes<1>>(), s.len()) }
}

/// `out[r] (+)= sum_c m[r][c] v[c]` (`m` row-major, `out.len()` rows, `v.len()` columns),
/// four rows at a time: four independent sums per entry of `v` loaded.
#[inline(always)]
pub fn rows_times<const L: usize>(out: &mut [Lanes<L>], m: &[f64], v: &[Lanes<L>], add: bool) {
    rows_times_skipping(out, m, v, add, 0);
}

/// [`rows_times`] skipping the blocks of four rows that [`zero_row_blocks`] found all zero
/// (`skip`; their rows of `out` are 0, or unchanged when `add`).
#[inline(always)]
pub fn rows_times_skipping<const L: usize>(out: &mut [Lanes<L>], m: &[f64], v: &[Lanes<L>], add: bool, skip: u64) {
    let cols = v.len();
    let rows = out.len();
    let mut r = 0;
    while r + 4 <= rows {
        if r / 4 < 64 && skip >> (r / 4) & 1 == 1 {
            if !add {
                out[r..r + 4].fill([0.0; L]);
            }
            r += 4;
            continue;
        }
        let (m0, m1) = (&m[r * cols..(r + 1) * cols], &m[(r + 1) * cols..(r + 2) * cols]);
        let (m2, m3) = (&m[(r + 2) * cols..(r + 3) * cols], &m[(r + 3) * cols..(r + 4) * cols]);
        let mut acc = [[0.0; L]; 4];
        for (c, vc) in v.iter().enumerate() {
            let (a0, a1, a2, a3) = (m0[c], m1[c], m2[c], m3[c]);
            for l in 0..L {
                acc[0][l] += a0 * vc[l];
                acc[1][l] += a1 * vc[l];
                acc[2][l] += a2 * vc[l];
                acc[3][l] += a3 * vc[l];
            }
        }
        for (o, a) in out[r..r + 4].iter_mut().zip(&acc) {
            for l in 0..L {
                o[l] = if add { o[l] + a[l] } else { a[l] };
            }
        }
        r += 4;
    }
    for (q, o) in out.iter_mut().enumerate().skip(r) {
        let row = &m[q * cols..(q + 1) * cols];
        let mut acc = [0.0; L];
        for (a, vc) in row.iter().zip(v) {
            for l in 0..L {
                acc[l] += a * vc[l];
            }
        }
        for l in 0..L {
            o[l] = if add { o[l] + acc[l] } else { acc[l] };
        }
    }
}

/// `out[c] += sum_r m[r][c] v[r]` (`m'` times `v`; `m` row-major, `v.len()` rows,
/// `out.len()` columns), four rows at a time: one load and store of `out[c]` per four
/// multiplies.
#[inline(always)]
pub fn cols_times_add<const L: usize>(out: &mut [Lanes<L>], m: &[f64], v: &[Lanes<L>]) {
    cols_times_add_skipping(out, m, v, 0);
}

/// [`cols_times_add`] skipping the blocks of four rows of `m` that [`zero_row_blocks`] found
/// all zero (`skip`).
#[inline(always)]
pub fn cols_times_add_skipping<const L: usize>(out: &mut [Lanes<L>], m: &[f64], v: &[Lanes<L>], skip: u64) {
    let cols = out.len();
    let rows = v.len();
    let mut r = 0;
    while r + 4 <= rows {
        if r / 4 < 64 && skip >> (r / 4) & 1 == 1 {
            r += 4;
            continue;
        }
        let (m0, m1) = (&m[r * cols..(r + 1) * cols], &m[(r + 1) * cols..(r + 2) * cols]);
        let (m2, m3) = (&m[(r + 2) * cols..(r + 3) * cols], &m[(r + 3) * cols..(r + 4) * cols]);
        let (v0, v1, v2, v3) = (v[r], v[r + 1], v[r + 2], v[r + 3]);
        for (c, o) in out.iter_mut().enumerate() {
            let (a0, a1, a2, a3) = (m0[c], m1[c], m2[c], m3[c]);
            for l in 0..L {
                o[l] += a0 * v0[l] + a1 * v1[l] + a2 * v2[l] + a3 * v3[l];
            }
        }
        r += 4;
    }
    for (q, vq) in v.iter().enumerate().skip(r) {
        for (a, o) in m[q * cols..(q + 1) * cols].iter().zip(out.iter_mut()) {
            for l in 0..L {
                o[l] += a * vq[l];
            }
        }
    }
}

/// One `RB x CB` block of [`outer_add`], its sums in registers over all steps.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn outer_block<const L: usize, const RB: usize, const CB: usize>(
    g: &mut [f64],
    a: &[Lanes<L>],
    rows: usize,
    b: &[Lanes<L>],
    cols: usize,
    steps: usize,
    i: usize,
    j: usize,
) {
    let mut acc = [[[0.0; L]; CB]; RB];
    for t in 0..steps {
        let at = &a[t * rows + i..t * rows + i + RB];
        let bt = &b[t * cols + j..t * cols + j + CB];
        for p in 0..RB {
            for q in 0..CB {
                for l in 0..L {
                    acc[p][q][l] += at[p][l] * bt[q][l];
                }
            }
        }
    }
    for (p, ap) in acc.iter().enumerate() {
        for (q, aq) in ap.iter().enumerate() {
            g[(i + p) * cols + j + q] += aq.iter().sum::<f64>();
        }
    }
}

/// `g[i][j] += sum_{t < steps} sum_l a[t][i][l] b[t][j][l]`: the outer products of `steps`
/// samples of `rows` and `cols` lane vectors (`g` row-major `rows x cols`), in register
/// blocks.
#[inline(always)]
pub fn outer_add<const L: usize>(
    g: &mut [f64],
    a: &[Lanes<L>],
    rows: usize,
    b: &[Lanes<L>],
    cols: usize,
    steps: usize,
) {
    let mut i = 0;
    while i + 4 <= rows {
        let mut j = 0;
        while j + 2 <= cols {
            outer_block::<L, 4, 2>(g, a, rows, b, cols, steps, i, j);
            j += 2;
        }
        if j < cols {
            outer_block::<L, 4, 1>(g, a, rows, b, cols, steps, i, j);
        }
        i += 4;
    }
    while i < rows {
        let mut j = 0;
        while j + 4 <= cols {
            outer_block::<L, 1, 4>(g, a, rows, b, cols, steps, i, j);
            j += 4;
        }
        while j < cols {
            outer_block::<L, 1, 1>(g, a, rows, b, cols, steps, i, j);
            j += 1;
        }
        i += 1;
    }
}

/// Bit `b` set when rows `4b .. 4b + 4` of `m` (row-major, `cols` columns) are all zero, for
/// the first 64 blocks: the products above skip them (an LFR's input-play channels have zero
/// rows in `G`: 12 of the 33 rows of the FSM model).
pub fn zero_row_blocks(m: &[f64], cols: usize) -> u64 {
    let rows = m.len().checked_div(cols).unwrap_or(0);
    let mut bits = 0;
    for b in 0..(rows / 4).min(64) {
        if m[4 * b * cols..4 * (b + 1) * cols].iter().all(|v| *v == 0.0) {
            bits |= 1 << b;
        }
    }
    bits
}
