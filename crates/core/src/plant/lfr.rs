//! The MIMO linear fractional representation (LFR) with hysteresis in its feedback path: a
//! discrete state space whose feedback channels pass through banks of play operators.
//!
//! ```text
//! z[t]   = G x[t] + H u[t]                    (nw feedback channels)
//! w_i[t] = sum_j weights[i, j] * play(z_i[t]; thresholds[i, j])          (i < nw - nt)
//! w_i[t] = sum_j weights[i, j] * r_ij tanh(z_i[t] / r_ij), r_ij = thresholds[i, j]   (the last nt)
//! y[t]   = C x[t] + D u[t] + F w[t]
//! x[t+1] = A x[t] + B u[t] + E w[t]
//! ```
//!
//! The last `nt` channels are static saturations (no memory: a smooth, odd, saturating
//! stiffness — with `G`, `E`, `F` free, a one-hidden-layer network in the feedback path);
//! the others are hysteretic (play operators). A static channel's slot in the state holds its
//! last output, so the state layout does not depend on `nt`.
//!
//! With `nw = 0` it is the plain linear MIMO state space; with `G = 0`, `H = I` a Hammerstein
//! model (hysteresis per actuator ahead of the dynamics). Matrices are row-major. The state is
//! `x` (`nx`) followed by the play operators' outputs (`nw * nr`, channel-major). A step
//! allocates nothing: the caller gives a scratch buffer of [`Lfr::scratch_len`].
use crate::error::{check_finite, ModelError};
#[cfg(doc)]
use crate::num::lanes::zero_row_blocks;
use crate::num::lanes::{one_lane, one_lane_mut, rows_times, rows_times_skipping, Lanes};
use crate::num::math::tanh;

/// The dimensions and matrices of an LFR model, borrowed (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct Lfr<'a> {
    /// States.
    pub nx: usize,
    /// Inputs.
    pub nu: usize,
    /// Outputs.
    pub ny: usize,
    /// Feedback channels.
    pub nw: usize,
    /// Play operators per feedback channel.
    pub nr: usize,
    /// The last `nt` channels are static saturations (`r tanh(z / r)`), not plays.
    pub nt: usize,
    /// `nx * nx`.
    pub a: &'a [f64],
    /// `nx * nu`.
    pub b: &'a [f64],
    /// `ny * nx`.
    pub c: &'a [f64],
    /// `ny * nu`.
    pub d: &'a [f64],
    /// `nx * nw`.
    pub e: &'a [f64],
    /// `ny * nw`.
    pub f: &'a [f64],
    /// `nw * nx`.
    pub g: &'a [f64],
    /// `nw * nu`.
    pub h: &'a [f64],
    /// `nw * nr` play thresholds (each ≥ 0).
    pub thresholds: &'a [f64],
    /// `nw * nr` play weights.
    pub weights: &'a [f64],
    /// Set by [`Lfr::validated`]: `A` is block diagonal with blocks of 1 or 2 states (a
    /// modal form), so a step reads only the blocks.
    pub modal: bool,
}

impl<'a> Lfr<'a> {
    /// Check every length and that all numbers are finite (thresholds ≥ 0). The error names the
    /// matrix  and the flat index.
    pub fn validated(self) -> Result<Self, ModelError> {
        let (nx, nu, ny, nw, nr) = (self.nx, self.nu, self.ny, self.nw, self.nr);
        let parts: [(&'static str, &[f64], usize); 10] = [
            ("A", self.a, nx * nx),
            ("B", self.b, nx * nu),
            ("C", self.c, ny * nx),
            ("D", self.d, ny * nu),
            ("E", self.e, nx * nw),
            ("F", self.f, ny * nw),
            ("G", self.g, nw * nx),
            ("H", self.h, nw * nu),
            ("thresholds", self.thresholds, nw * nr),
            ("weights", self.weights, nw * nr),
        ];
        for (name, v, len) in parts {
            if v.len() != len {
                return Err(ModelError::Length(name, len, v.len()));
            }
            check_finite(name, v)?;
        }
        if let Some(k) = self.thresholds.iter().position(|&r| r < 0.0) {
            return Err(ModelError::Negative("thresholds", k, self.thresholds[k]));
        }
        if self.nt > nw {
            return Err(ModelError::Structure("nt (static channels, at most nw)", self.nt));
        }
        let first_static = (nw - self.nt) * nr;
        if let Some(k) = self.thresholds[first_static..].iter().position(|&r| r <= 0.0) {
            let k = first_static + k;
            return Err(ModelError::NotPositive("static-channel thresholds", k, self.thresholds[k]));
        }
        let mut out = self;
        out.modal = is_modal(self.a, nx);
        Ok(out)
    }

    /// Length of the state: `nx + nw * nr`.
    pub fn state_len(&self) -> usize {
        self.nx + self.nw * self.nr
    }

    /// Length of the scratch buffer a step needs: `nx + nw`.
    pub fn scratch_len(&self) -> usize {
        self.nx + self.nw
    }

    /// One sample: reads `u` (`nu`), writes `y` (`ny`) and `z` (`nw`), advances `state`
    /// (`[x, plays]`, [`Lfr::state_len`]) with `scratch` ([`Lfr::scratch_len`]): [`Lfr::step_lanes`]
    /// for one record.
    #[inline]
    pub fn step(&self, u: &[f64], state: &mut [f64], scratch: &mut [f64], y: &mut [f64], z: &mut [f64]) {
        let (x, plays) = one_lane_mut(state).split_at_mut(self.nx);
        let (xn, w) = one_lane_mut(scratch).split_at_mut(self.nx);
        self.step_lanes(one_lane(u), x, plays, xn, w, one_lane_mut(y), one_lane_mut(z), None, 0);
    }

    /// One sample of `L` records in lockstep ([`crate::num::lanes`]): reads `u` (`nu`),
    /// writes `y` (`ny`), the feedback signals `z` and outputs `w` (`nw` each), advances the
    /// states `x` (`nx`) and `plays` (`nw * nr`) through `xn` (`nx`, scratch). `slopes`
    /// (`nw * nr`), when given, gets each play's move (0 stuck, 1 up: `p = z - r`, 2 down:
    /// `p = z + r`) and each static channel's `dp/dz`, for the adjoint. `g_zero`: the blocks
    /// of four rows of `G` known to be zero ([`zero_row_blocks`]; 0: none skipped).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn step_lanes<const L: usize>(
        &self,
        u: &[Lanes<L>],
        x: &mut [Lanes<L>],
        plays: &mut [Lanes<L>],
        xn: &mut [Lanes<L>],
        w: &mut [Lanes<L>],
        y: &mut [Lanes<L>],
        z: &mut [Lanes<L>],
        mut slopes: Option<&mut [Lanes<L>]>,
        g_zero: u64,
    ) {
        let (nx, nw, nr) = (self.nx, self.nw, self.nr);
        let first_static = nw - self.nt;
        rows_times_skipping(z, self.g, x, false, g_zero);
        rows_times(z, self.h, u, true);
        for (i, zi) in z.iter_mut().enumerate() {
            // an overflowed feedback signal is NaN, not a clipped infinity: the divergence shows
            for v in zi.iter_mut() {
                if !v.is_finite() {
                    *v = f64::NAN;
                }
            }
            let mut wi = [0.0; L];
            for j in 0..nr {
                let k = i * nr + j;
                let (r, wk) = (self.thresholds[k], self.weights[k]);
                let p = &mut plays[k];
                if i >= first_static {
                    for l in 0..L {
                        let th = tanh(zi[l] / r);
                        p[l] = r * th;
                        if let Some(sl) = slopes.as_deref_mut() {
                            sl[k][l] = 1.0 - th * th;
                        }
                    }
                } else {
                    if let Some(sl) = slopes.as_deref_mut() {
                        for l in 0..L {
                            sl[k][l] = if r == 0.0 || p[l] < zi[l] - r {
                                1.0
                            } else if p[l] > zi[l] + r {
                                2.0
                            } else {
                                0.0
                            };
                        }
                    }
                    for l in 0..L {
                        p[l] = p[l].max(zi[l] - r).min(zi[l] + r);
                    }
                }
                for l in 0..L {
                    wi[l] += wk * p[l];
                }
            }
            w[i] = wi;
        }
        rows_times(y, self.c, x, false);
        rows_times(y, self.d, u, true);
        rows_times(y, self.f, w, true);
        if self.modal {
            for (s, xs) in xn.iter_mut().enumerate() {
                let row = &self.a[s * nx..(s + 1) * nx];
                let mut acc = [0.0; L];
                for c in s.saturating_sub(1)..(s + 2).min(nx) {
                    for l in 0..L {
                        acc[l] += row[c] * x[c][l];
                    }
                }
                *xs = acc;
            }
        } else {
            rows_times(xn, self.a, x, false);
        }
        rows_times(xn, self.b, u, true);
        rows_times(xn, self.e, w, true);
        x.copy_from_slice(xn);
    }

    /// Simulate `n` samples of `u` (`n * nu`, sample-major) from `state` (advanced in place)
    /// into `y` (`n * ny`) and `z` (`n * nw`). Stops early (returning `false`) when `stop`
    /// says so, checked every 1024 samples; returns `false` too when the state diverges.
    pub fn simulate(
        &self,
        u: &[f64],
        state: &mut [f64],
        scratch: &mut [f64],
        y: &mut [f64],
        z: &mut [f64],
        stop: &dyn Fn() -> bool,
    ) -> bool {
        let (nu, ny, nw) = (self.nu, self.ny, self.nw);
        let n = u.len().checked_div(nu).unwrap_or(0);
        for t in 0..n {
            if t % 1024 == 0 && (stop() || !state.iter().all(|s| s.is_finite())) {
                return false;
            }
            self.step(
                &u[t * nu..(t + 1) * nu],
                state,
                scratch,
                &mut y[t * ny..(t + 1) * ny],
                &mut z[t * nw..(t + 1) * nw],
            );
        }
        state.iter().all(|s| s.is_finite())
    }
}

/// Run a bank of play operators: `x` (`n * m`, sample-major, `m` channels), `thresholds`
/// (`m * nr`), `state` (`m * nr`, advanced in place), `out` (`n * m * nr`).
pub fn play_bank(x: &[f64], m: usize, thresholds: &[f64], state: &mut [f64], out: &mut [f64]) {
    let nr = thresholds.len().checked_div(m).unwrap_or(0);
    let n = x.len().checked_div(m).unwrap_or(0);
    for t in 0..n {
        for i in 0..m {
            let xi = x[t * m + i];
            for j in 0..nr {
                let k = i * nr + j;
                let r = thresholds[k];
                let p = state[k].max(xi - r).min(xi + r);
                state[k] = p;
                out[(t * m + i) * nr + j] = p;
            }
        }
    }
}

/// Whether `a` (`n x n`) has nonzeros only in diagonal blocks of 1 or 2 states.
fn is_modal(a: &[f64], n: usize) -> bool {
    let mut s = 0;
    while s < n {
        // a block of 2 when the entry right of the diagonal or below it is nonzero
        let two = s + 1 < n && (a[s * n + s + 1] != 0.0 || a[(s + 1) * n + s] != 0.0);
        let size = if two { 2 } else { 1 };
        for r in s..s + size {
            for c in 0..n {
                if (c < s || c >= s + size) && a[r * n + c] != 0.0 {
                    return false;
                }
            }
        }
        s += size;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_order_siso_and_play_feedback() {
        // x+ = 0.5 x + u, y = x; with a play of threshold 0 (identity) fed back with E = -0.25
        let (a, b, c, d) = ([0.5], [1.0], [1.0], [0.0]);
        let lin = Lfr {
            nx: 1,
            nu: 1,
            ny: 1,
            nw: 0,
            nr: 0,
            a: &a,
            b: &b,
            c: &c,
            d: &d,
            e: &[],
            f: &[],
            g: &[],
            h: &[],
            thresholds: &[],
            weights: &[],
            nt: 0,
            modal: false,
        }
        .validated()
        .unwrap();
        let u = [1.0, 0.0, 0.0];
        let (mut st, mut sc, mut y, mut z) = ([0.0], [0.0], [0.0; 3], [0.0; 0]);
        assert!(lin.simulate(&u, &mut st, &mut sc, &mut y, &mut z, &|| false));
        assert_eq!(y, [0.0, 1.0, 0.5]);
        let fb = Lfr {
            nx: 1,
            nu: 1,
            ny: 1,
            nw: 1,
            nr: 1,
            a: &a,
            b: &b,
            c: &c,
            d: &d,
            e: &[-0.25],
            f: &[0.0],
            g: &[1.0],
            h: &[0.0],
            thresholds: &[0.0],
            weights: &[1.0],
            nt: 0,
            modal: false,
        }
        .validated()
        .unwrap();
        let (mut st, mut sc, mut y, mut z) = ([0.0, 0.0], [0.0, 0.0], [0.0; 3], [0.0; 3]);
        assert!(fb.simulate(&u, &mut st, &mut sc, &mut y, &mut z, &|| false));
        // the loop is x+ = 0.25 x + u
        assert_eq!(y, [0.0, 1.0, 0.25]);
        assert_eq!(z, y);
    }

    #[test]
    fn modal_fast_path_equals_dense() {
        // two 2x2 blocks and a 1x1: the block path and the dense path agree
        #[rustfmt::skip]
        let a = [
            0.9, -0.2, 0.0, 0.0, 0.0,
            0.2, 0.9, 0.0, 0.0, 0.0,
            0.0, 0.0, 0.5, 0.1, 0.0,
            0.0, 0.0, -0.1, 0.5, 0.0,
            0.0, 0.0, 0.0, 0.0, 0.7,
        ];
        let (b, c, d) = ([1.0, 0.5, -1.0, 0.2, 1.0], [1.0, 0.0, 1.0, 0.0, 1.0], [0.0]);
        let m = Lfr {
            nx: 5,
            nu: 1,
            ny: 1,
            nw: 0,
            nr: 0,
            a: &a,
            b: &b,
            c: &c,
            d: &d,
            e: &[],
            f: &[],
            g: &[],
            h: &[],
            thresholds: &[],
            weights: &[],
            nt: 0,
            modal: false,
        };
        let fast = m.validated().unwrap();
        assert!(fast.modal);
        let u = [1.0, -0.5, 0.25, 0.0, 2.0, 0.0];
        let run = |m: &Lfr<'_>| {
            let (mut st, mut sc, mut y, mut z) = ([0.0; 5], [0.0; 5], [0.0; 6], [0.0; 0]);
            m.simulate(&u, &mut st, &mut sc, &mut y, &mut z, &|| false);
            y
        };
        assert_eq!(run(&fast), run(&m));
        let mut full = a;
        full[4] = 0.1; // a coupling outside the blocks
        assert!(!is_modal(&full, 5));
    }

    #[test]
    fn a_static_channel_is_a_saturation_without_memory() {
        // y = w = 0.5 tanh(z / 0.5), z = u: the same input gives the same output whatever came before
        let (a, b, c, d) = ([0.0], [0.0], [0.0], [0.0]);
        let m = Lfr {
            nx: 1,
            nu: 1,
            ny: 1,
            nw: 1,
            nr: 1,
            a: &a,
            b: &b,
            c: &c,
            d: &d,
            e: &[0.0],
            f: &[1.0],
            g: &[0.0],
            h: &[1.0],
            thresholds: &[0.5],
            weights: &[1.0],
            nt: 1,
            modal: false,
        }
        .validated()
        .unwrap();
        let u = [0.2, 3.0, 0.2, -3.0, 0.2];
        let (mut st, mut sc, mut y, mut z) = ([0.0, 0.0], [0.0, 0.0], [0.0; 5], [0.0; 5]);
        assert!(m.simulate(&u, &mut st, &mut sc, &mut y, &mut z, &|| false));
        assert_eq!(y[0], 0.5 * tanh(0.4));
        assert_eq!((y[2], y[4]), (y[0], y[0]));
        assert!((y[1] - 0.5).abs() < 1e-4 && (y[3] + 0.5).abs() < 1e-4);
        // its scale must be > 0 (a play's threshold may be 0), and nt <= nw
        let zero = Lfr { thresholds: &[0.0], ..m }.validated().unwrap_err();
        assert!(zero == ModelError::NotPositive("static-channel thresholds", 0, 0.0));
        assert!(Lfr { thresholds: &[0.0], nt: 0, ..m }.validated().is_ok());
        assert!(Lfr { nt: 2, ..m }.validated().is_err());
    }

    #[test]
    fn wrong_length_is_named() {
        let e = Lfr {
            nx: 2,
            nu: 1,
            ny: 1,
            nw: 0,
            nr: 0,
            a: &[0.0; 3],
            b: &[0.0; 2],
            c: &[0.0; 2],
            d: &[0.0],
            e: &[],
            f: &[],
            g: &[],
            h: &[],
            thresholds: &[],
            weights: &[],
            nt: 0,
            modal: false,
        }
        .validated()
        .unwrap_err();
        assert!(e == ModelError::Length("A", 4, 3));
    }
}
