//! The gradient of an LFR simulation's squared output error with respect to every parameter
//! ([`crate::lfr::Lfr`]): reverse mode (backpropagation through time).
//!
//! The loss of one record is `weight * sum_{t >= skip} |y[t] - y_meas[t]|^2`. The forward
//! pass runs the model from the given state and stores the trajectory (states, feedback
//! outputs, play outputs and whether each play moved); the backward pass runs the adjoint
//! from the last sample to the first:
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
//! `d thresholds_k += gp_k (p / r - (z / r) (1 - (p / r)^2))`, its `mu_k = 0`. Nothing is allocated: the caller
//! gives one work buffer per record ([`work_len`]) for the trajectory and the adjoint. For a modal `A` (see
//! [`Lfr::validated`]) only the entries inside its diagonal blocks get a gradient (the
//! others stay 0: a modal parameterization keeps them 0).
use crate::lfr::Lfr;
use crate::num::linalg::dot;
use crate::num::math::tanh;

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

/// Length of the work buffer [`loss_grad`] needs for a record of `n` samples: the stored
/// trajectory (`n * (nx + nw + 2 nw nr + ny)`) and the adjoint's buffers.
pub fn work_len(m: &Lfr<'_>, n: usize) -> usize {
    let np = m.nw * m.nr;
    n * (m.nx + m.nw + 2 * np + m.ny) + m.state_len() + m.scratch_len() + 3 * m.nw + 2 * m.nx + np + m.ny
}

/// The loss of one record (see the module docs) and its gradient added to `grad`
/// ([`grad_len`], layout of [`grad_offsets`]). `u` (`n * nu`), `y_meas` (`n * ny`),
/// `state0` ([`Lfr::state_len`]), `work` at least [`work_len`] (the caller's: the core never
/// allocates). Returns `None` when the simulation diverges (a state not
/// finite) or `stop` says so (checked every 1024 samples); `grad` is then left partly
/// updated.
#[allow(clippy::too_many_arguments)]
pub fn loss_grad(
    m: &Lfr<'_>,
    u: &[f64],
    y_meas: &[f64],
    state0: &[f64],
    skip: usize,
    weight: f64,
    grad: &mut [f64],
    work: &mut [f64],
    stop: &dyn Fn() -> bool,
) -> Option<f64> {
    let (nx, nu, ny, nw, nr) = (m.nx, m.nu, m.ny, m.nw, m.nr);
    let np = nw * nr;
    let n = u.len().checked_div(nu).unwrap_or(y_meas.len().checked_div(ny).unwrap_or(0));
    // the forward pass: the trajectory the backward pass reads
    let (xs, work) = work.split_at_mut(n * nx);
    let (ws, work) = work.split_at_mut(n * nw);
    let (ps, work) = work.split_at_mut(n * np);
    let (mv, work) = work.split_at_mut(n * np); // 0 stuck, 1 moved up (p = z - r), 2 down (p = z + r)
    let (es, work) = work.split_at_mut(n * ny);
    let (state, work) = work.split_at_mut(m.state_len());
    let (scratch, work) = work.split_at_mut(m.scratch_len());
    let (z, work) = work.split_at_mut(nw);
    let (lam, work) = work.split_at_mut(nx); // dL/dx[t+1]
    let (lam_new, work) = work.split_at_mut(nx);
    let (mu, work) = work.split_at_mut(np); // dL/dp[t] through p[t+1]
    let (gy, work) = work.split_at_mut(ny);
    let (gw, work) = work.split_at_mut(nw);
    let (gz, _) = work.split_at_mut(nw);
    state.copy_from_slice(state0);
    let mut loss = 0.0;
    for t in 0..n {
        if t % 1024 == 0 && (stop() || !state.iter().all(|s| s.is_finite())) {
            return None;
        }
        xs[t * nx..(t + 1) * nx].copy_from_slice(&state[..nx]);
        let ut = &u[t * nu..(t + 1) * nu];
        let yt = &mut es[t * ny..(t + 1) * ny];
        m.step(ut, state, scratch, yt, z);
        ws[t * nw..(t + 1) * nw].copy_from_slice(&scratch[nx..nx + nw]);
        // which plays moved: from the feedback signal the step computed (z) and the plays
        // before it (the previous sample's, stored)
        let prev = if t == 0 { &state0[nx..] } else { &ps[(t - 1) * np..t * np] };
        for (i, &zi) in z.iter().enumerate() {
            for j in 0..nr {
                let k = i * nr + j;
                let r = m.thresholds[k];
                if i >= nw - m.nt {
                    // a static channel: its slope dp/dz
                    let th = tanh(zi / r);
                    mv[t * np + k] = 1.0 - th * th;
                    continue;
                }
                mv[t * np + k] = if r == 0.0 || prev[k] < zi - r {
                    1.0
                } else if prev[k] > zi + r {
                    2.0
                } else {
                    0.0
                };
            }
        }
        ps[t * np..(t + 1) * np].copy_from_slice(&state[nx..]);
        for (o, e) in yt.iter_mut().enumerate() {
            *e -= y_meas[t * ny + o];
            if t >= skip {
                loss += weight * *e * *e;
            }
        }
    }
    if !(loss.is_finite() && state.iter().all(|s| s.is_finite())) {
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
    lam.fill(0.0);
    mu.fill(0.0);
    for t in (0..n).rev() {
        if t % 1024 == 0 && stop() {
            return None;
        }
        let x = &xs[t * nx..(t + 1) * nx];
        let ut = &u[t * nu..(t + 1) * nu];
        let wt = &ws[t * nw..(t + 1) * nw];
        for (o, g) in gy.iter_mut().enumerate() {
            *g = if t >= skip { 2.0 * weight * es[t * ny + o] } else { 0.0 };
        }
        // gw = F' gy + E' lam (row by row: contiguous reads)
        gw.fill(0.0);
        for (o, &g) in gy.iter().enumerate() {
            if g != 0.0 {
                axpy(gw, g, &m.f[o * nw..(o + 1) * nw]);
            }
        }
        for (r, &l) in lam.iter().enumerate() {
            if l != 0.0 {
                axpy(gw, l, &m.e[r * nw..(r + 1) * nw]);
            }
        }
        // outputs: C, D, F
        for o in 0..ny {
            let g = gy[o];
            if g != 0.0 {
                axpy(&mut gc[o * nx..(o + 1) * nx], g, x);
                axpy(&mut gd[o * nu..(o + 1) * nu], g, ut);
                axpy(&mut gf[o * nw..(o + 1) * nw], g, wt);
            }
        }
        // states: A (blocks), B, E
        let mut s0 = 0;
        while s0 < nx {
            let size = block_at(m, s0);
            for r in s0..s0 + size {
                let l = lam[r];
                for c in s0..s0 + size {
                    ga[r * nx + c] += l * x[c];
                }
            }
            s0 += size;
        }
        for r in 0..nx {
            let l = lam[r];
            if l != 0.0 {
                axpy(&mut gb[r * nu..(r + 1) * nu], l, ut);
                axpy(&mut ge[r * nw..(r + 1) * nw], l, wt);
            }
        }
        // the plays
        for i in 0..nw {
            let mut s = 0.0;
            if i >= nw - m.nt {
                let zi = dot(&m.g[i * nx..(i + 1) * nx], x) + dot(&m.h[i * nu..(i + 1) * nu], ut);
                for j in 0..nr {
                    let k = i * nr + j;
                    let (r, p, slope) = (m.thresholds[k], ps[t * np + k], mv[t * np + k]);
                    let gp = m.weights[k] * gw[i];
                    gwt[k] += gw[i] * p;
                    s += gp * slope;
                    gth[k] += gp * (p / r - zi / r * slope);
                }
                gz[i] = s;
                if s != 0.0 {
                    axpy(&mut gg[i * nx..(i + 1) * nx], s, x);
                    axpy(&mut gh[i * nu..(i + 1) * nu], s, ut);
                }
                continue;
            }
            for j in 0..nr {
                let k = i * nr + j;
                let gp = m.weights[k] * gw[i] + mu[k];
                gwt[k] += gw[i] * ps[t * np + k];
                let dir = mv[t * np + k];
                if dir == 0.0 {
                    mu[k] = gp;
                } else {
                    s += gp;
                    mu[k] = 0.0;
                    if m.thresholds[k] > 0.0 {
                        gth[k] += if dir == 1.0 { -gp } else { gp };
                    }
                }
            }
            gz[i] = s;
            if s != 0.0 {
                axpy(&mut gg[i * nx..(i + 1) * nx], s, x);
                axpy(&mut gh[i * nu..(i + 1) * nu], s, ut);
            }
        }
        // lam[t] = A' lam[t+1] + C' gy + G' gz
        let mut s0 = 0;
        while s0 < nx {
            let size = block_at(m, s0);
            for (c, ln) in lam_new.iter_mut().enumerate().skip(s0).take(size) {
                *ln = lam.iter().enumerate().skip(s0).take(size).map(|(r, l)| m.a[r * nx + c] * l).sum();
            }
            s0 += size;
        }
        for (o, &g) in gy.iter().enumerate() {
            if g != 0.0 {
                axpy(lam_new, g, &m.c[o * nx..(o + 1) * nx]);
            }
        }
        for (i, &g) in gz.iter().enumerate() {
            if g != 0.0 {
                axpy(lam_new, g, &m.g[i * nx..(i + 1) * nx]);
            }
        }
        lam.copy_from_slice(lam_new);
    }
    Some(loss)
}

#[inline]
fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
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
        let (nx, nu, ny, nw, nr) = (4, 2, 2, 2, 3);
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
        Owned { nx, nu, ny, nw, nr, nt, p }
    }

    fn loss_of(m: &Owned, u: &[f64], y: &[f64], s0: &[f64], skip: usize) -> f64 {
        let mut g = vec![0.0; m.p.len()];
        let mut w = vec![0.0; work_len(&m.lfr(), u.len() / m.nu)];
        loss_grad(&m.lfr(), u, y, s0, skip, 0.7, &mut g, &mut w, &|| false).unwrap()
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let mut seed = 7u64;
        for (modal, nt) in [(true, 0), (false, 0), (true, 1), (false, 2)] {
            let m = model(&mut seed, modal, nt);
            let n = 200;
            let u: Vec<f64> = (0..n * m.nu).map(|_| rand(&mut seed)).collect();
            let y: Vec<f64> = (0..n * m.ny).map(|_| 0.3 * rand(&mut seed)).collect();
            let s0: Vec<f64> = (0..m.nx + m.nw * m.nr).map(|_| 0.1 * rand(&mut seed)).collect();
            let skip = 20;
            let lfr = m.lfr();
            assert_eq!(lfr.modal, modal);
            let mut g = vec![0.0; m.p.len()];
            let mut w = vec![0.0; work_len(&lfr, n)];
            let l0 = loss_grad(&lfr, &u, &y, &s0, skip, 0.7, &mut g, &mut w, &|| false).unwrap();
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
        let mut w = vec![0.0; work_len(&lfr, n)];
        let l = loss_grad(&lfr, &u, &y, &s0, 0, 1.0, &mut g, &mut w, &|| false).unwrap();
        assert_eq!(l, 0.0);
        assert!(g.iter().all(|v| *v == 0.0));
        // an unstable model diverges: None
        let mut bad = Owned { p: m.p.clone(), ..m };
        bad.p[10] = 1e200;
        let long: Vec<f64> = (0..3000 * bad.nu).map(|_| 1.0).collect();
        let yl = vec![0.0; 3000 * bad.ny];
        let mut g = vec![0.0; bad.p.len()];
        let mut w = vec![0.0; work_len(&bad.lfr(), 3000)];
        assert!(loss_grad(&bad.lfr(), &long, &yl, &s0, 0, 1.0, &mut g, &mut w, &|| false).is_none());
    }
}
