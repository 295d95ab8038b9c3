//! Discretized Preisach model (docs/spec.md §2.7).
//!
//! The Preisach half-plane `lo <= beta <= alpha <= hi` is cut into an `L x L` triangular
//! grid of cells; cell `(i, j)` (alpha in row i, beta in column j, `j <= i`) holds the total
//! weight `w_ij >= 0` of the relays in it, spread uniformly over the cell. Relays are 0
//! (down) or 1 (up), so
//!
//! ```text
//! y = offset + slope*v + mass of the "up" region
//! ```
//!
//! The up region is the staircase left by the alternating dominant extrema of the input
//! (memory with wiping-out), and its mass is a sum of Everett integrals
//! `E(a, b) = mass{ b <= beta <= alpha <= a }`, evaluated exactly for the piecewise
//! constant density. The output is therefore continuous in `v` (piecewise quadratic),
//! which is what makes the per-sample inverse exact. Input outside `[lo, hi]` saturates
//! every relay, as the physics says; it is not clipped.
//!
//! Start: negative saturation (all relays down). State layout:
//! `[v_prev, len, e_1 .. e_memory]`, the extrema alternating max, min, max, ...
//! When a new extremum would exceed `memory`, the adjacent pair of extrema closest in value
//! is merged away (the smallest nested minor loop is forgotten; its mass is the error).
use crate::error::{check_finite, check_scalar, ModelError};
use crate::hysteresis::{Hysteresis, Invertible};

/// Largest memory depth (number of stored extrema).
pub const MAX_MEMORY: usize = 256;

/// Most grid levels (`levels (levels + 1) / 2` cells: 500,500 weights at the limit).
pub const MAX_LEVELS: usize = 1000;

/// Number of cells of an `levels x levels` triangular grid.
pub const fn cell_count(levels: usize) -> usize {
    levels * (levels + 1) / 2
}

/// Index of cell (row i, column j <= i) in the weight slice.
#[inline(always)]
pub const fn cell_index(i: usize, j: usize) -> usize {
    i * (i + 1) / 2 + j
}

/// Preisach configuration.
#[derive(Debug, Clone, Copy)]
pub struct Preisach<'a> {
    /// Lower edge of the grid (input units).
    pub lo: f64,
    /// Upper edge of the grid.
    pub hi: f64,
    /// Grid levels `L`.
    pub levels: usize,
    /// Cell weights, row-major over the triangle: `cell_index(i, j)`, `j <= i`.
    pub weights: &'a [f64],
    /// Row prefix sums `prefix[cell_index(i, j)] = sum_{j' < j} w_{i j'}` (see [`row_prefix`]).
    pub prefix: &'a [f64],
    /// Constant output term.
    pub offset: f64,
    /// Linear output term (> 0 keeps the model strictly increasing).
    pub slope: f64,
    /// Memory depth (stored extrema), 2..=MAX_MEMORY.
    pub memory: usize,
}

/// Fill `prefix` with the row prefix sums of `weights` (call once per parameter set).
pub fn row_prefix(levels: usize, weights: &[f64], prefix: &mut [f64]) {
    for i in 0..levels {
        let mut acc = 0.0;
        for j in 0..=i {
            prefix[cell_index(i, j)] = acc;
            acc += weights[cell_index(i, j)];
        }
    }
}

impl<'a> Preisach<'a> {
    /// Validate a configuration built as a struct literal; returns it unchanged. `prefix`
    /// must have been filled by [`row_prefix`].
    pub fn validated(self) -> Result<Self, ModelError> {
        let Preisach { lo, hi, levels, weights, prefix, offset, slope, memory } = self;
        check_scalar("lo", lo)?;
        check_scalar("hi", hi)?;
        if !(hi > lo) {
            return Err(ModelError::NotIncreasing("input_range", 1, hi));
        }
        if levels == 0 || levels > MAX_LEVELS {
            return Err(ModelError::Structure("levels", levels));
        }
        if !(2..=MAX_MEMORY).contains(&memory) {
            return Err(ModelError::Structure("memory", memory));
        }
        let n = cell_count(levels);
        if weights.len() != n {
            return Err(ModelError::Length("weights", n, weights.len()));
        }
        if prefix.len() != n {
            return Err(ModelError::Length("prefix", n, prefix.len()));
        }
        check_finite("weights", weights)?;
        for (i, &w) in weights.iter().enumerate() {
            if w < 0.0 {
                return Err(ModelError::Negative("weights", i, w));
            }
        }
        check_scalar("offset", offset)?;
        check_scalar("slope", slope)?;
        if slope < 0.0 {
            return Err(ModelError::Negative("slope", usize::MAX, slope));
        }
        Ok(self)
    }

    #[inline]
    fn cell_of(&self, x: f64) -> (usize, f64) {
        // x in [lo, hi] -> (cell, position within cell in [0, 1])
        let t = (x - self.lo) / (self.hi - self.lo) * self.levels as f64;
        let mut i = t as usize; // t >= 0
        if i >= self.levels {
            i = self.levels - 1;
        }
        (i, t - i as f64)
    }

    /// Everett integral: mass of `{ b <= beta <= alpha <= a }`.
    pub fn everett(&self, a: f64, b: f64) -> f64 {
        let a = if a > self.hi { self.hi } else { a };
        let b = if b < self.lo { self.lo } else { b };
        if !(a > b) {
            return 0.0;
        }
        let (ia, fa) = self.cell_of(a);
        let (jb, fb) = self.cell_of(b);
        let mut mass = 0.0;
        for i in jb..=ia {
            // alpha-extent of row i inside [b, a], as fractions of a cell
            let a_hi = if i == ia { fa } else { 1.0 };
            let a_lo = if i == jb { fb } else { 0.0 };
            if !(a_hi > a_lo) {
                continue;
            }
            let row_frac = a_hi - a_lo;
            // off-diagonal cells j < i: full columns right of b, and b's partial column
            if i > jb {
                let full = self.prefix[cell_index(i, i)] - self.prefix[cell_index(i, jb + 1)];
                mass += row_frac * (full + self.weights[cell_index(i, jb)] * (1.0 - fb));
            }
            // diagonal cell: triangle beta' in [max(cell start, b), alpha']
            let start = if i == jb { fb } else { 0.0 };
            let span = a_hi - start;
            mass += self.weights[cell_index(i, i)] * span * span;
        }
        mass
    }

    /// Add `sign *` the fraction of each cell inside `{ b <= beta <= alpha <= a }` to `out`
    /// (one slot per cell): the cell-by-cell form of [`Preisach::everett`], whose weighted
    /// sum it is.
    fn everett_cells(&self, a: f64, b: f64, sign: f64, out: &mut [f64]) {
        let a = if a > self.hi { self.hi } else { a };
        let b = if b < self.lo { self.lo } else { b };
        if !(a > b) {
            return;
        }
        let (ia, fa) = self.cell_of(a);
        let (jb, fb) = self.cell_of(b);
        for i in jb..=ia {
            let a_hi = if i == ia { fa } else { 1.0 };
            let a_lo = if i == jb { fb } else { 0.0 };
            if !(a_hi > a_lo) {
                continue;
            }
            let row_frac = a_hi - a_lo;
            if i > jb {
                out[cell_index(i, jb)] += sign * row_frac * (1.0 - fb);
                for j in jb + 1..i {
                    out[cell_index(i, j)] += sign * row_frac;
                }
            }
            let start = if i == jb { fb } else { 0.0 };
            let span = a_hi - start;
            out[cell_index(i, i)] += sign * span * span;
        }
    }

    /// Fraction of each cell's relays that are up (one slot per cell, overwritten): the
    /// regressors of the weights, `output = offset + slope v + weights . fractions`.
    pub fn cell_fractions(&self, state: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|x| *x = 0.0);
        let v = state[0];
        let len = state[1] as usize;
        let ext = &state[2..2 + len];
        let n = ext.len() + 1;
        let at = |k: usize| if k < ext.len() { ext[k] } else { v };
        let mut k = 0;
        let mut m_prev = self.lo;
        while k < n {
            let big = at(k);
            self.everett_cells(big, m_prev, 1.0, out);
            if k + 1 < n {
                let m = at(k + 1);
                self.everett_cells(big, m, -1.0, out);
                m_prev = m;
            }
            k += 2;
        }
    }

    /// Output for the extrema `ext` followed by the current input `v` (max-first).
    fn output(&self, ext: &[f64], v: f64) -> f64 {
        // y = sum over maxima M_k of E(M_k, m_{k-1}) - E(M_k, m_k), m_0 = lo
        let mut y = self.offset + self.slope * v;
        let n = ext.len() + 1;
        let at = |k: usize| if k < ext.len() { ext[k] } else { v };
        let mut k = 0;
        let mut m_prev = self.lo;
        while k < n {
            let big = at(k);
            y += self.everett(big, m_prev);
            if k + 1 < n {
                let m = at(k + 1);
                y -= self.everett(big, m);
                m_prev = m;
            }
            k += 2;
        }
        y
    }

    /// Update the extrema stack `ext[..len]` for the new input; returns the new length.
    fn update(&self, ext: &mut [f64], mut len: usize, v_prev: f64, v: f64) -> usize {
        if v == v_prev {
            return len;
        }
        let rising_phase = len % 2 == 0;
        let rising = v > v_prev;
        if rising != rising_phase {
            // reversal: v_prev becomes an extremum, unless it sits in saturation
            // (falling out of negative saturation leaves nothing to remember)
            let all_down = !rising && len == 0 && v_prev <= self.lo;
            // v_prev is wiped at once (with the last stored extremum as its partner) when v
            // already passes that extremum; it then needs no slot, and nothing is forgotten
            let wiped_at_once = if rising { len >= 1 && ext[len - 1] <= v } else { len >= 2 && ext[len - 1] >= v };
            if wiped_at_once {
                len -= 1;
            } else if !all_down {
                if len == self.memory {
                    len = self.forget_smallest_loop(ext, len);
                }
                ext[len] = v_prev;
                len += 1;
            }
        }
        // wiping-out: v passing an earlier extremum erases it with its partner
        if rising {
            while len >= 2 && ext[len - 2] <= v {
                len -= 2;
            }
        } else {
            while len >= 3 && ext[len - 2] >= v {
                len -= 2;
            }
            if len == 1 && v <= self.lo {
                len = 0; // negative saturation erases everything
            }
        }
        len
    }

    fn forget_smallest_loop(&self, ext: &mut [f64], len: usize) -> usize {
        let mut best = 0;
        let mut best_gap = f64::INFINITY;
        for j in 0..len - 1 {
            let gap = crate::num::math::abs(ext[j] - ext[j + 1]);
            if gap < best_gap {
                best_gap = gap;
                best = j;
            }
        }
        ext.copy_within(best + 2..len, best);
        len - 2
    }
}

impl Hysteresis for Preisach<'_> {
    fn state_len(&self) -> usize {
        2 + self.memory
    }
    fn reset(&self, state: &mut [f64]) {
        state.iter_mut().for_each(|s| *s = 0.0);
        state[0] = self.lo; // negative saturation
    }
    /// Besides finite slots: `state[1]` (the number of stored extrema) is a whole number in
    /// `0..=memory` (a larger one would index past the buffer).
    fn check_state(&self, state: &[f64]) -> Result<(), ModelError> {
        crate::hysteresis::check_state_len(state, self.state_len())?;
        check_finite("state", state)?;
        let len = state[1];
        if !((0.0..=self.memory as f64).contains(&len) && len == libm::trunc(len)) {
            return Err(ModelError::OutOfRange("state (memory length)", 1, len, 0.0, self.memory as f64));
        }
        Ok(())
    }
    fn step(&self, state: &mut [f64], v: f64) -> f64 {
        let (head, ext) = state.split_at_mut(2);
        let len = self.update(ext, head[1] as usize, head[0], v);
        head[0] = v;
        head[1] = len as f64;
        self.output(&ext[..len], v)
    }
}

impl Invertible for Preisach<'_> {
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64) {
        let mut buf = [0.0; MAX_MEMORY];
        let len = state[1] as usize;
        buf[..len].copy_from_slice(&state[2..2 + len]);
        let len = self.update(&mut buf, len, state[0], v);
        (self.output(&buf[..len], v), f64::NAN)
    }
}
