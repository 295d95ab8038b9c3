//! The gradient of an LFR simulation's squared output error with respect to every parameter
//! ([`crate::lfr::Lfr`]): reverse mode (backpropagation through time), `L` records at once.
//!
//! The loss of one record is `weight * sum_{t >= skip} |y[t] - y_meas[t]|^2`. The forward
//! pass runs the model from the given state and stores the trajectory (states, feedback
//! signals and outputs, play outputs and whether each play moved); the backward pass runs the
//! adjoint from the last sample to the first:
//!
//! ```text
//! gy      = 2 weight (y[t] - y_meas[t])            (0 for t < skip)
//! gw      = F' gy + E' lam[t+1]
//! gp_k    = weights_k gw_i + mu_k                   (mu_k: what p_k[t] is worth later)
//! gz_i   += gp_k  and mu_k = 0    when play k moved (p = z -/+ r)
//!           mu_k = gp_k           when it was stuck (p[t] = p[t-1])
//! lam[t]  = A' lam[t+1] + C' gy + G' gz
//! ```
//!
//! and the parameter gradients are the outer products (`dA += lam[t+1] x[t]'`, `dC += gy x[t]'`,
//! `dG += gz x[t]'`, ...), `d weights_k += gw_i p_k[t]`, `d thresholds_k -= gp_k` when the play
//! moved up (`p = z - r`), `+= gp_k` when it moved down. A static channel (the last `nt`:
//! `p = r tanh(z / r)`, no memory) passes `gz_i += gp_k (1 - (p / r)^2)` and
//! `d thresholds_k += gp_k (p / r - (z / r) (1 - (p / r)^2))`, its `mu_k = 0`.
//!
//! Why `L` records in lockstep: one record's step is a string of matrix-vector products whose
//! every matrix entry is loaded for one multiply; `L` records stepped together
//! (lane-interleaved vectors, [`Lanes`]) load it once for `L` multiplies, and the inner loops
//! over lanes carry no reduction, so they vectorize. The outer products are deferred: the
//! adjoint vectors of [`CHUNK`] steps are kept and added as one blocked product (its
//! accumulators in registers), not as a rank-one update of the whole gradient per step.
//! Nothing is allocated: the caller gives one work buffer per batch ([`work_len`]). For a
//! modal `A` (see [`Lfr::validated`]) only the entries inside its diagonal blocks get a
//! gradient (the others stay 0: a modal parameterization keeps them 0).
use crate::lfr::Lfr;
use crate::num::lanes::{cols_times_add, cols_times_add_skipping, outer_add, zero_row_blocks, Lanes};

/// Backward steps between two additions of the deferred outer products (their adjoint
/// vectors and the trajectory they multiply stay in the L2 cache).
pub const CHUNK: usize = 64;

/// Offsets of each parameter's gradient in the flat gradient vector, in the order
/// `A, B, C, D, E, F, G, H, thresholds, weights` (each row-major, shapes as in [`Lfr`]).
pub fn grad_offsets(m: &Lfr<'_>) -> [usize; 11] {
    let (nx, nu, ny, nw, nr) = (m.nx, m.nu, m.ny, m.nw, m.nr);
    let lens = [nx * nx, nx * nu, ny * nx, ny * nu, nx * nw, ny * nw, nw * nx, nw * nu, nw * nr, nw * nr];
    let mut off = [0; 11];
    for (i, l) in lens.iter().enumerate() {
        off[i + 1] = off[i] + l;
    }
    off
}

/// Length of the flat gradient vector.
pub fn grad_len(m: &Lfr<'_>) -> usize {
    grad_offsets(m)[10]
}

/// The size of the diagonal block of `A` starting at state `s`: 1 or 2 for a modal `A`, else
/// the rest of the matrix (one dense block).
#[inline]
fn block_at(m: &Lfr<'_>, s: usize) -> usize {
    let n = m.nx;
    if !m.modal {
        return n - s;
    }
    if s + 1 < n && (m.a[s * n + s + 1] != 0.0 || m.a[(s + 1) * n + s] != 0.0) {
        2
    } else {
        1
    }
}

/// Length, in lane vectors, of the work buffer [`loss_grad`] needs for records of `n`
/// samples: the stored trajectory (`n * (2 nx + 2 nw + 2 nw nr + ny + nu)`: states, feedback
/// signals and outputs, plays and their slopes, errors, inputs), the deferred adjoint vectors
/// and the step's vectors.
pub fn work_len(m: &Lfr<'_>, n: usize) -> usize {
    let (nx, nu, ny, nw) = (m.nx, m.nu, m.ny, m.nw);
    let np = nw * m.nr;
    n * (nx + 2 * nw + 2 * np + ny + nu) + CHUNK * (nx + ny + nw) + 6 * nx + 4 * np + 4 * nw + 2 * ny
}

/// The losses of `L` records of the same length (see the module docs) and the gradient of
/// their sum added to `grad` ([`grad_len`], layout of [`grad_offsets`]). Record `l`:
/// `u[l]` (`n * nu`), `y_meas[l]` (`n * ny`), `state0[l]` ([`Lfr::state_len`]), `weight[l]`;
/// `work` at least [`work_len`] lane vectors (the caller's: the core never allocates). A
/// record of weight 0 adds nothing (a batch's padding). Returns `None` when a simulation
/// diverges (a state not finite) or `stop` says so (checked every 1024 samples); `grad` is
/// then left partly updated.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn loss_grad<const L: usize>(
    m: &Lfr<'_>,
    u: [&[f64]; L],
    y_meas: [&[f64]; L],
    state0: [&[f64]; L],
    skip: usize,
    weight: [f64; L],
    grad: &mut [f64],
    work: &mut [Lanes<L>],
    stop: &dyn Fn() -> bool,
) -> Option<[f64; L]> {
    let (nx, nu, ny, nw, nr) = (m.nx, m.nu, m.ny, m.nw, m.nr);
    let np = nw * nr;
    let n = u[0].len().checked_div(nu).unwrap_or(y_meas[0].len().checked_div(ny).unwrap_or(0));
    let (xs, work) = work.split_at_mut(n * nx);
    let (ws, work) = work.split_at_mut(n * nw);
    let (zs, work) = work.split_at_mut(n * nw);
    let (ps, work) = work.split_at_mut(n * np);
    // a play: 0 stuck, 1 moved up (p = z - r), 2 down (p = z + r); a static channel: dp/dz
    let (mv, work) = work.split_at_mut(n * np);
    let (es, work) = work.split_at_mut(n * ny);
    let (us, work) = work.split_at_mut(n * nu);
    let (lamc, work) = work.split_at_mut(CHUNK * nx); // lam[t+1] of the chunk's steps
    let (gyc, work) = work.split_at_mut(CHUNK * ny);
    let (gzc, work) = work.split_at_mut(CHUNK * nw);
    let (x, work) = work.split_at_mut(nx);
    let (xn, work) = work.split_at_mut(nx);
    let (plays, work) = work.split_at_mut(np);
    let (z, work) = work.split_at_mut(nw);
    let (w, work) = work.split_at_mut(nw);
    let (yv, work) = work.split_at_mut(ny);
    let (lam, work) = work.split_at_mut(nx); // dL/dx[t+1]
    let (lam_new, work) = work.split_at_mut(nx);
    let (mu, work) = work.split_at_mut(np); // dL/dp[t] through p[t+1]
    let (gy, work) = work.split_at_mut(ny);
    let (gw, work) = work.split_at_mut(nw);
    let (gz, work) = work.split_at_mut(nw);
    let (ga_l, work) = work.split_at_mut(2 * nx); // a modal A's blocks, per lane
    let (gth_l, work) = work.split_at_mut(np);
    let (gwt_l, _) = work.split_at_mut(np);
    for t in 0..n {
        for j in 0..nu {
            for l in 0..L {
                us[t * nu + j][l] = u[l][t * nu + j];
            }
        }
    }
    for l in 0..L {
        for s in 0..nx {
            x[s][l] = state0[l][s];
        }
        for k in 0..np {
            plays[k][l] = state0[l][nx + k];
        }
    }
    let finite =
        |x: &[Lanes<L>], plays: &[Lanes<L>]| x.iter().chain(plays.iter()).all(|v| v.iter().all(|s| s.is_finite()));
    let first_static = nw - m.nt;
    let g_zero = zero_row_blocks(m.g, nx);
    let mut loss = [0.0; L];
    // the forward pass: the trajectory the backward pass reads
    for t in 0..n {
        if t % 1024 == 0 && (stop() || !finite(x, plays)) {
            return None;
        }
        xs[t * nx..(t + 1) * nx].copy_from_slice(x);
        let ut = &us[t * nu..(t + 1) * nu];
        m.step_lanes(ut, x, plays, xn, w, yv, z, Some(&mut mv[t * np..(t + 1) * np]), g_zero);
        zs[t * nw..(t + 1) * nw].copy_from_slice(z);
        ws[t * nw..(t + 1) * nw].copy_from_slice(w);
        ps[t * np..(t + 1) * np].copy_from_slice(plays);
        for (o, yo) in yv.iter().enumerate() {
            let e = &mut es[t * ny + o];
            for l in 0..L {
                e[l] = yo[l] - y_meas[l][t * ny + o];
                if t >= skip {
                    loss[l] += weight[l] * e[l] * e[l];
                }
            }
        }
    }
    if !(loss.iter().all(|l| l.is_finite()) && finite(x, plays)) {
        return None;
    }
    // the backward pass
    let off = grad_offsets(m);
    let (ga, rest) = grad.split_at_mut(off[1]);
    let (gb, rest) = rest.split_at_mut(off[2] - off[1]);
    let (gc, rest) = rest.split_at_mut(off[3] - off[2]);
    let (gd, rest) = rest.split_at_mut(off[4] - off[3]);
    let (ge, rest) = rest.split_at_mut(off[5] - off[4]);
    let (gf, rest) = rest.split_at_mut(off[6] - off[5]);
    let (gg, rest) = rest.split_at_mut(off[7] - off[6]);
    let (gh, rest) = rest.split_at_mut(off[8] - off[7]);
    let (gth, gwt) = rest.split_at_mut(off[9] - off[8]);
    for v in [&mut *lam, &mut *mu, &mut *ga_l, &mut *gth_l, &mut *gwt_l] {
        v.fill([0.0; L]);
    }
    for t in (0..n).rev() {
        if t % 1024 == 0 && stop() {
            return None;
        }
        let c = t % CHUNK; // the step's place in its chunk
        let xt = &xs[t * nx..(t + 1) * nx];
        for (o, g) in gy.iter_mut().enumerate() {
            for l in 0..L {
                g[l] = if t >= skip { 2.0 * weight[l] * es[t * ny + o][l] } else { 0.0 };
            }
        }
        gyc[c * ny..(c + 1) * ny].copy_from_slice(gy);
        lamc[c * nx..(c + 1) * nx].copy_from_slice(lam);
        gw.fill([0.0; L]);
        cols_times_add(gw, m.f, gy);
        cols_times_add(gw, m.e, lam);
        if m.modal {
            let mut s0 = 0;
            while s0 < nx {
                let size = block_at(m, s0);
                for r in s0..s0 + size {
                    let (gr, lr) = (&mut ga_l[2 * r..2 * r + size], lam[r]);
                    for (g, xq) in gr.iter_mut().zip(&xt[s0..s0 + size]) {
                        for l in 0..L {
                            g[l] += lr[l] * xq[l];
                        }
                    }
                }
                s0 += size;
            }
        }
        // the plays
        let (pt, mvt, zt) = (&ps[t * np..(t + 1) * np], &mv[t * np..(t + 1) * np], &zs[t * nw..(t + 1) * nw]);
        for i in 0..nw {
            let mut s = [0.0; L];
            for j in 0..nr {
                let k = i * nr + j;
                let (r, wk) = (m.thresholds[k], m.weights[k]);
                let (p, sl, g) = (pt[k], mvt[k], gw[i]);
                for l in 0..L {
                    gwt_l[k][l] += g[l] * p[l];
                }
                if i >= first_static {
                    let zi = zt[i];
                    for l in 0..L {
                        let gp = wk * g[l];
                        s[l] += gp * sl[l];
                        gth_l[k][l] += gp * (p[l] / r - zi[l] / r * sl[l]);
                    }
                    continue;
                }
                // selects, not branches, so that the lanes vectorize: a play that moved passes
                // its worth to z (and to its threshold), a stuck one carries it to the sample before
                for l in 0..L {
                    let gp = wk * g[l] + mu[k][l];
                    let moved = sl[l] != 0.0;
                    s[l] += if moved { gp } else { 0.0 };
                    mu[k][l] = if moved { 0.0 } else { gp };
                    if r > 0.0 {
                        gth_l[k][l] += if sl[l] == 1.0 {
                            -gp
                        } else if sl[l] == 2.0 {
                            gp
                        } else {
                            0.0
                        };
                    }
                }
            }
            gz[i] = s;
        }
        gzc[c * nw..(c + 1) * nw].copy_from_slice(gz);
        // lam[t] = A' lam[t+1] + C' gy + G' gz
        if m.modal {
            for (q, ln) in lam_new.iter_mut().enumerate() {
                let mut acc = [0.0; L];
                let lo = q.saturating_sub(1);
                for (r, lr) in lam.iter().enumerate().take((q + 2).min(nx)).skip(lo) {
                    let a = m.a[r * nx + q];
                    for l in 0..L {
                        acc[l] += a * lr[l];
                    }
                }
                *ln = acc;
            }
        } else {
            lam_new.fill([0.0; L]);
            cols_times_add(lam_new, m.a, lam);
        }
        cols_times_add(lam_new, m.c, gy);
        cols_times_add_skipping(lam_new, m.g, gz, g_zero);
        lam.copy_from_slice(lam_new);
        if c == 0 {
            // the chunk's outer products, from its first sample `t`
            let k = CHUNK.min(n - t);
            let (xc, wc, uc) = (&xs[t * nx..], &ws[t * nw..], &us[t * nu..]);
            if !m.modal {
                outer_add(ga, lamc, nx, xc, nx, k);
            }
            outer_add(gb, lamc, nx, uc, nu, k);
            outer_add(gc, gyc, ny, xc, nx, k);
            outer_add(gd, gyc, ny, uc, nu, k);
            outer_add(ge, lamc, nx, wc, nw, k);
            outer_add(gf, gyc, ny, wc, nw, k);
            outer_add(gg, gzc, nw, xc, nx, k);
            outer_add(gh, gzc, nw, uc, nu, k);
        }
    }
    if m.modal {
        let mut s0 = 0;
        while s0 < nx {
            let size = block_at(m, s0);
            for r in s0..s0 + size {
                for q in s0..s0 + size {
                    ga[r * nx + q] += ga_l[2 * r + q - s0].iter().sum::<f64>();
                }
            }
            s0 += size;
        }
    }
    for k in 0..np {
        gth[k] += gth_l[k].iter().sum::<f64>();
        gwt[k] += gwt_l[k].iter().sum::<f64>();
    }
    Some(loss)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic pseudo-random sequence (no dependency).
    fn rand(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    struct Owned {
        nx: usize,
        nu: usize,
        ny: usize,
        nw: usize,
        nr: usize,
        nt: usize,
        p: Vec<f64>, // flat, in the gradient's layout
    }

    /// The dimensions `nx, nu, ny, nw, nr, nt` of a model without its matrices (for
    /// [`grad_offsets`]).
    fn shell(d: [usize; 6]) -> Lfr<'static> {
        let [nx, nu, ny, nw, nr, nt] = d;
        Lfr {
            nx,
            nu,
            ny,
            nw,
            nr,
            a: &[],
            b: &[],
            c: &[],
            d: &[],
            e: &[],
            f: &[],
            g: &[],
            h: &[],
            thresholds: &[],
            weights: &[],
            nt,
            modal: false,
        }
    }

    impl Owned {
        fn lfr(&self) -> Lfr<'_> {
            let shell = shell([self.nx, self.nu, self.ny, self.nw, self.nr, self.nt]);
            let o = grad_offsets(&shell);
            let p = &self.p;
            Lfr {
                a: &p[o[0]..o[1]],
                b: &p[o[1]..o[2]],
                c: &p[o[2]..o[3]],
                d: &p[o[3]..o[4]],
                e: &p[o[4]..o[5]],
                f: &p[o[5]..o[6]],
                g: &p[o[6]..o[7]],
                h: &p[o[7]..o[8]],
                thresholds: &p[o[8]..o[9]],
                weights: &p[o[9]..o[10]],
                ..shell
            }
            .validated()
            .unwrap()
        }
    }

    /// A random model; `nt` of its 2 channels static (their thresholds 0.2, 0.5, 1).
    fn model(seed: &mut u64, modal: bool, nt: usize) -> Owned {
        model_nw(seed, modal, nt, 2)
    }

    /// [`model`] with `nw` channels; with 8 or more, rows 4..8 of `G` are 0 (channels fed by
    /// the inputs only, as an LFR's input plays: the products skip that block).
    fn model_nw(seed: &mut u64, modal: bool, nt: usize, nw: usize) -> Owned {
        let (nx, nu, ny, nr) = (4, 2, 2, 3);
        let shell = shell([nx, nu, ny, nw, nr, nt]);
        let o = grad_offsets(&shell);
        let mut p: Vec<f64> = (0..o[10]).map(|_| 0.5 * rand(seed)).collect();
        // A: a stable modal form (a 2x2 rotation block, two real poles) or a small dense matrix
        let a = &mut p[o[0]..o[1]];
        if modal {
            a.fill(0.0);
            let (re, im) = (0.8 * 0.9f64.cos(), 0.8 * 0.9f64.sin());
            a[0] = re;
            a[1] = -im;
            a[4] = im;
            a[5] = re;
            a[10] = 0.6;
            a[15] = -0.5;
        } else {
            for v in a.iter_mut() {
                *v *= 0.5;
            }
        }
        for (k, th) in p[o[8]..o[9]].iter_mut().enumerate() {
            *th = if k / nr >= nw - nt { [0.2, 0.5, 1.0][k % 3] } else { [0.0, 0.1, 0.3][k % 3] };
        }
        if nw >= 8 {
            p[o[6] + 4 * nx..o[6] + 8 * nx].fill(0.0);
        }
        Owned { nx, nu, ny, nw, nr, nt, p }
    }

    fn loss_of(m: &Owned, u: &[f64], y: &[f64], s0: &[f64], skip: usize) -> f64 {
        let mut g = vec![0.0; m.p.len()];
        let mut w = vec![[0.0]; work_len(&m.lfr(), u.len() / m.nu)];
        loss_grad(&m.lfr(), [u], [y], [s0], skip, [0.7], &mut g, &mut w, &|| false).unwrap()[0]
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let mut seed = 7u64;
        for (modal, nt, nw) in [(true, 0, 2), (false, 0, 2), (true, 1, 2), (false, 2, 2), (true, 1, 9)] {
            let m = model_nw(&mut seed, modal, nt, nw);
            let g_zero = zero_row_blocks(&m.p[grad_offsets(&m.lfr())[6]..grad_offsets(&m.lfr())[7]], m.nx);
            assert_eq!(g_zero, if nw == 9 { 0b10 } else { 0 });
            let n = 200;
            let u: Vec<f64> = (0..n * m.nu).map(|_| rand(&mut seed)).collect();
            let y: Vec<f64> = (0..n * m.ny).map(|_| 0.3 * rand(&mut seed)).collect();
            let s0: Vec<f64> = (0..m.nx + m.nw * m.nr).map(|_| 0.1 * rand(&mut seed)).collect();
            let skip = 20;
            let lfr = m.lfr();
            assert_eq!(lfr.modal, modal);
            let mut g = vec![0.0; m.p.len()];
            let mut w = vec![[0.0]; work_len(&lfr, n)];
            let l0 = loss_grad(&lfr, [&u], [&y], [&s0], skip, [0.7], &mut g, &mut w, &|| false).unwrap()[0];
            assert!(l0 > 0.0);
            let off = grad_offsets(&lfr);
            let mut checked = 0;
            for (k, &gk) in g.iter().enumerate() {
                if modal && k < off[1] && m.p[k] == 0.0 {
                    continue; // outside the blocks: not a parameter of the modal form
                }
                if k >= off[8] && k < off[9] && m.p[k] == 0.0 {
                    continue; // a threshold at 0 is not differentiable (it is a kink)
                }
                let h = 1e-6;
                let mut mp = Owned { p: m.p.clone(), ..m };
                mp.p[k] += h;
                let lp = loss_of(&mp, &u, &y, &s0, skip);
                mp.p[k] -= 2.0 * h;
                let lm = loss_of(&mp, &u, &y, &s0, skip);
                let fd = (lp - lm) / (2.0 * h);
                let rel = (fd - gk).abs() / (fd.abs().max(gk.abs()).max(1e-3 * l0));
                assert!(rel < 1e-5, "modal {modal}, nt {nt}, parameter {k}: fd {fd} vs adjoint {}", gk);
                checked += 1;
            }
            assert!(checked > 50);
        }
    }

    #[test]
    fn records_in_lockstep_equal_records_alone() {
        // three records and a padding lane of weight 0 in one batch of 4: the same losses and
        // the same summed gradient as each record alone (up to the order of the sums)
        let mut seed = 11u64;
        for (modal, nt) in [(true, 1), (false, 0)] {
            let m = model(&mut seed, modal, nt);
            let lfr = m.lfr();
            let n = 150;
            let rec = |seed: &mut u64| -> (Vec<f64>, Vec<f64>, Vec<f64>) {
                let u = (0..n * m.nu).map(|_| rand(seed)).collect();
                let y = (0..n * m.ny).map(|_| 0.3 * rand(seed)).collect();
                let s0 = (0..lfr.state_len()).map(|_| 0.1 * rand(seed)).collect();
                (u, y, s0)
            };
            let recs: Vec<_> = (0..3).map(|_| rec(&mut seed)).collect();
            let weights = [0.7, 1.3, 0.4];
            let mut alone = vec![0.0; m.p.len()];
            let mut losses = [0.0; 3];
            for (i, (u, y, s0)) in recs.iter().enumerate() {
                let mut w = vec![[0.0]; work_len(&lfr, n)];
                losses[i] =
                    loss_grad(&lfr, [u], [y], [s0], 13, [weights[i]], &mut alone, &mut w, &|| false).unwrap()[0];
            }
            let (r0, r1, r2) = (&recs[0], &recs[1], &recs[2]);
            let mut batch = vec![0.0; m.p.len()];
            let mut w = vec![[0.0; 4]; work_len(&lfr, n)];
            let l = loss_grad(
                &lfr,
                [&r0.0, &r1.0, &r2.0, &r0.0],
                [&r0.1, &r1.1, &r2.1, &r1.1],
                [&r0.2, &r1.2, &r2.2, &r2.2],
                13,
                [weights[0], weights[1], weights[2], 0.0],
                &mut batch,
                &mut w,
                &|| false,
            )
            .unwrap();
            for i in 0..3 {
                assert!((l[i] - losses[i]).abs() <= 1e-12 * losses[i], "loss {i}: {} vs {}", l[i], losses[i]);
            }
            let scale = alone.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (k, (a, b)) in alone.iter().zip(&batch).enumerate() {
                assert!((a - b).abs() <= 1e-11 * scale, "modal {modal}, parameter {k}: {a} alone, {b} in the batch");
            }
            assert!(alone.iter().filter(|v| **v != 0.0).count() > 50);
        }
    }

    #[test]
    fn zero_error_has_zero_gradient_and_divergence_is_none() {
        let mut seed = 3u64;
        let m = model(&mut seed, true, 1);
        let lfr = m.lfr();
        let n = 50;
        let u: Vec<f64> = (0..n * m.nu).map(|_| rand(&mut seed)).collect();
        let s0 = vec![0.0; lfr.state_len()];
        let mut y = vec![0.0; n * m.ny];
        let mut z = vec![0.0; n * m.nw];
        let (mut st, mut sc) = (s0.clone(), vec![0.0; lfr.scratch_len()]);
        assert!(lfr.simulate(&u, &mut st, &mut sc, &mut y, &mut z, &|| false));
        let mut g = vec![0.0; m.p.len()];
        let mut w = vec![[0.0]; work_len(&lfr, n)];
        let l = loss_grad(&lfr, [&u], [&y], [&s0], 0, [1.0], &mut g, &mut w, &|| false).unwrap()[0];
        assert_eq!(l, 0.0);
        assert!(g.iter().all(|v| *v == 0.0));
        // an unstable model diverges: None
        let mut bad = Owned { p: m.p.clone(), ..m };
        bad.p[10] = 1e200;
        let long: Vec<f64> = (0..3000 * bad.nu).map(|_| 1.0).collect();
        let yl = vec![0.0; 3000 * bad.ny];
        let mut g = vec![0.0; bad.p.len()];
        let mut w = vec![[0.0]; work_len(&bad.lfr(), 3000)];
        assert!(loss_grad(&bad.lfr(), [&long], [&yl], [&s0], 0, [1.0], &mut g, &mut w, &|| false).is_none());
    }
}
