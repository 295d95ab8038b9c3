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
