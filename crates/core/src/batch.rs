//! Lane kernels for batch evaluation: `LANES` parameter sets advance together on one input
//! record, so the per-sample work is element-wise across lanes and vectorizes. The
//! arithmetic per lane is exactly that of the single-model `step`, in the same order, so a
//! batch result is bit-identical to simulating each set alone.
use crate::math::clamp;

/// Parameter sets processed together.
pub const LANES: usize = 8;

/// One lane-vector of `f64`.
pub type Lanes = [f64; LANES];

/// Classical PI for `LANES` parameter sets: `r`, `w`, `z` are `[operator][lane]`; the
/// outputs of `v[k]` go to `y[k]` (`y.len() >= v.len()`). Kept free of callbacks so the
/// compiler sees plain element-wise loops.
#[inline(always)]
pub fn pi_lanes(p0: &Lanes, r: &[Lanes], w: &[Lanes], z: &mut [Lanes], v: &[f64], y: &mut [Lanes]) {
    let n = r.len().min(w.len()).min(z.len());
    let (r, w, z) = (&r[..n], &w[..n], &mut z[..n]);
    for (yk, &vk) in y.iter_mut().zip(v) {
        let mut acc = [0.0; LANES];
        for l in 0..LANES {
            acc[l] = p0[l] * vk;
        }
        for i in 0..n {
            let (ri, wi, zi) = (&r[i], &w[i], &mut z[i]);
            for l in 0..LANES {
                zi[l] = clamp(zi[l], vk - ri[l], vk + ri[l]);
                acc[l] += wi[l] * zi[l];
            }
        }
        *yk = acc;
    }
}
