//! Lane kernels for batch evaluation: `LANES` parameter sets advance together on one input
//! record, so the per-sample work is element-wise across lanes and vectorizes. The
//! arithmetic per lane is exactly that of the single-model `step`, in the same order, so a
//! batch result is bit-identical to simulating each set alone.
use crate::math::clamp;

/// Lane width the batch engine uses.
pub const LANES: usize = 8;

/// Classical PI for `L` parameter sets: `r`, `w`, `z` are `[operator][lane]`; the
/// outputs of `v[k]` go to `y[k]` (`y.len() >= v.len()`). Kept free of callbacks so the
/// compiler sees plain element-wise loops.
#[inline(always)]
pub fn pi_lanes<const L: usize>(
    p0: &[f64; L],
    r: &[[f64; L]],
    w: &[[f64; L]],
    z: &mut [[f64; L]],
    v: &[f64],
    y: &mut [[f64; L]],
) {
    let n = r.len().min(w.len()).min(z.len());
    let (r, w, z) = (&r[..n], &w[..n], &mut z[..n]);
    for (yk, &vk) in y.iter_mut().zip(v) {
        let mut acc = [0.0; L];
        for l in 0..L {
            acc[l] = p0[l] * vk;
        }
        for i in 0..n {
            let (ri, wi, zi) = (&r[i], &w[i], &mut z[i]);
            for l in 0..L {
                zi[l] = clamp(zi[l], vk - ri[l], vk + ri[l]);
                acc[l] += wi[l] * zi[l];
            }
        }
        *yk = acc;
    }
}

/// [`pi_lanes`] with the operator count `N` known at compile time: the operator loop
/// unrolls and the play states stay in registers. Same arithmetic, same order, same bits.
#[inline(always)]
pub fn pi_lanes_fixed<const L: usize, const N: usize>(
    p0: &[f64; L],
    r: &[[f64; L]; N],
    w: &[[f64; L]; N],
    z: &mut [[f64; L]; N],
    v: &[f64],
    y: &mut [[f64; L]],
) {
    let mut zz = *z;
    for (yk, &vk) in y.iter_mut().zip(v) {
        let mut acc = [0.0; L];
        for l in 0..L {
            acc[l] = p0[l] * vk;
        }
        for i in 0..N {
            for l in 0..L {
                zz[i][l] = clamp(zz[i][l], vk - r[i][l], vk + r[i][l]);
                acc[l] += w[i][l] * zz[i][l];
            }
        }
        *yk = acc;
    }
    *z = zz;
}

// ---------------------------------------------------------------------------------------
// classical-PI parameter groups (the fastest batch path; used by the Python binding and
// callable from the C library): `L` rows of one input record at once, outputs or sums of
// squared errors.

/// Samples go through the lane kernels in short blocks so the outputs stay in L1.
pub const BLOCK: usize = 16;

/// Operator counts up to this get a kernel unrolled at compile time (no scratch needed).
pub const MAX_FIXED_OPERATORS: usize = 12;

/// Hand one block of lane outputs to the caller's sink: either rows of `out` (`(used, nv)`
/// row-major) or the running sums of squared errors against `target`.
#[inline(always)]
fn drain_block<const L: usize>(
    y: &[[f64; L]],
    k0: usize,
    used: usize,
    nv: usize,
    out: &mut [f64],
    target: Option<&[f64]>,
    sse: &mut [f64; L],
) {
    match target {
        None => {
            for l in 0..used {
                for (j, yk) in y.iter().enumerate() {
                    out[l * nv + k0 + j] = yk[l];
                }
            }
        }
        Some(t) => {
            for (yk, &tk) in y.iter().zip(&t[k0..]) {
                for l in 0..L {
                    let e = yk[l] - tk;
                    sse[l] += e * e;
                }
            }
        }
    }
}

/// Lane-major parameters of up to `L` PI rows `p0, r[n], w[n]` (padded with the last row).
fn gather<const L: usize>(n: usize, rows: &[&[f64]], r: &mut [[f64; L]], w: &mut [[f64; L]]) -> [f64; L] {
    let mut p0 = [0.0; L];
    for l in 0..L {
        let row = rows[l.min(rows.len() - 1)];
        p0[l] = row[0];
        for i in 0..n {
            r[i][l] = row[1 + i];
            w[i][l] = row[1 + n + i];
        }
    }
    p0
}

/// `L` classical-PI parameter sets at once (rows already valid, at most `L`), any `n`;
/// `scratch` holds at least `3 n` lanes.
#[inline(always)]
fn pi_group_body<const L: usize>(
    n: usize,
    rows: &[&[f64]],
    v: &[f64],
    out: &mut [f64],
    target: Option<&[f64]>,
    scratch: &mut [[f64; L]],
) {
    let (r, rest) = scratch.split_at_mut(n);
    let (w, rest) = rest.split_at_mut(n);
    let z = &mut rest[..n];
    z.iter_mut().for_each(|x| *x = [0.0; L]);
    let p0 = gather(n, rows, r, w);
    let mut y = [[0.0; L]; BLOCK];
    let mut sse = [0.0; L];
    for (b, vb) in v.chunks(BLOCK).enumerate() {
        pi_lanes(&p0, r, w, z, vb, &mut y);
        drain_block(&y[..vb.len()], b * BLOCK, rows.len(), v.len(), out, target, &mut sse);
    }
    if target.is_some() {
        out[..rows.len()].copy_from_slice(&sse[..rows.len()]);
    }
}

/// As [`pi_group_body`] with `N` operators fixed at compile time (states in registers).
/// Kept as a separate copy on purpose: passing the kernel as a closure that captures the
/// lane states cost 4x in throughput (the states left the registers).
#[inline(always)]
fn pi_group_fixed<const L: usize, const N: usize>(rows: &[&[f64]], v: &[f64], out: &mut [f64], target: Option<&[f64]>) {
    let mut r = [[0.0; L]; N];
    let mut w = [[0.0; L]; N];
    let mut z = [[0.0; L]; N];
    let p0 = gather(N, rows, &mut r, &mut w);
    let mut y = [[0.0; L]; BLOCK];
    let mut sse = [0.0; L];
    for (b, vb) in v.chunks(BLOCK).enumerate() {
        pi_lanes_fixed(&p0, &r, &w, &mut z, vb, &mut y);
        drain_block(&y[..vb.len()], b * BLOCK, rows.len(), v.len(), out, target, &mut sse);
    }
    if target.is_some() {
        out[..rows.len()].copy_from_slice(&sse[..rows.len()]);
    }
}

/// Dispatch on the operator count: the common sizes (1..=12, seed 2 uses 9) get an
/// unrolled kernel, larger ones the general loop.
#[inline(always)]
fn pi_group_any<const L: usize>(
    n: usize,
    rows: &[&[f64]],
    v: &[f64],
    out: &mut [f64],
    target: Option<&[f64]>,
    scratch: &mut [[f64; L]],
) {
    macro_rules! fixed {
        ($($n:literal)*) => {
            match n {
                $($n => pi_group_fixed::<L, $n>(rows, v, out, target),)*
                _ => pi_group_body::<L>(n, rows, v, out, target, scratch),
            }
        };
    }
    fixed!(1 2 3 4 5 6 7 8 9 10 11 12)
}

#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx512f")]
unsafe fn pi_group_avx512<const L: usize>(
    n: usize,
    rows: &[&[f64]],
    v: &[f64],
    out: &mut [f64],
    target: Option<&[f64]>,
    scratch: &mut [[f64; L]],
) {
    pi_group_any::<L>(n, rows, v, out, target, scratch)
}

#[cfg(all(feature = "std", target_arch = "x86_64"))]
#[target_feature(enable = "avx2")]
unsafe fn pi_group_avx2<const L: usize>(
    n: usize,
    rows: &[&[f64]],
    v: &[f64],
    out: &mut [f64],
    target: Option<&[f64]>,
    scratch: &mut [[f64; L]],
) {
    pi_group_any::<L>(n, rows, v, out, target, scratch)
}

/// Up to `L` valid classical-PI rows (`p0, r[n], w[n]`, no creep) on one input record `v`.
/// Without `target`, row `l`'s outputs go to `out[l * v.len() ..][.. v.len()]`; with it,
/// `out[l]` receives the row's sum of squared errors against `target`. `scratch` holds at
/// least `3 n` lanes when `n > MAX_FIXED_OPERATORS` (else it may be empty). With the `std`
/// feature the widest instruction set the CPU has is used: the same arithmetic on every
/// path (no FMA contraction), so it only changes the speed, never the bits.
pub fn pi_group<const L: usize>(
    n: usize,
    rows: &[&[f64]],
    v: &[f64],
    out: &mut [f64],
    target: Option<&[f64]>,
    scratch: &mut [[f64; L]],
) {
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    {
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F
            return unsafe { pi_group_avx512::<L>(n, rows, v, out, target, scratch) };
        }
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2
            return unsafe { pi_group_avx2::<L>(n, rows, v, out, target, scratch) };
        }
    }
    pi_group_any::<L>(n, rows, v, out, target, scratch)
}
