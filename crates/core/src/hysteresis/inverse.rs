//! The exact per-sample inverse (docs/spec.md §2.1).
//!
//! At sample k, with the forward states frozen at k-1, the map `v -> y(k)` is continuous and
//! increasing. We bracket the desired output, then refine with Newton steps on the active
//! segment (exact in one step on a linear piece), falling back to bisection whenever Newton
//! leaves the bracket. The forward states are then advanced with the found `v`, so the
//! inverse never drifts from the model it inverts.
use crate::error::ModelError;
use crate::hysteresis::Invertible;
use crate::num::math::abs;

/// Largest number of bracket expansions (each doubles the step): reaching 2^200 means the
/// target is out of range, not that we were unlucky.
const MAX_EXPANSIONS: usize = 200;
/// Bisection on f64 needs at most ~64 halvings once bracketed; Newton steps come on top.
const MAX_REFINEMENTS: usize = 200;

/// Solve `f(v).0 = target` for an increasing `f` returning `(value, slope)`, starting at
/// `guess`. Returns `None` if no bracket is found (target out of range, or `f` not finite).
pub fn solve_increasing<F: Fn(f64) -> (f64, f64)>(f: F, target: f64, guess: f64) -> Option<f64> {
    if !target.is_finite() || !guess.is_finite() {
        return None;
    }
    // A residual this small is the model's own rounding (its output is a sum of terms, each
    // rounded): any point there solves the equation as well as the model can be evaluated,
    // so the search stops instead of walking to the adjacent floats around the root.
    let resolution = 4.0 * f64::EPSILON * abs(target);
    let (y0, d0) = f(guess);
    let r0 = y0 - target;
    if abs(r0) <= resolution {
        return Some(guess);
    }
    if !r0.is_finite() {
        return None;
    }
    // first trial step: Newton if the slope is usable, else a unit-scaled step
    let dir = if r0 > 0.0 { -1.0 } else { 1.0 };
    let mut step = if d0 > 0.0 && d0.is_finite() { abs(r0) / d0 } else { 0.0 };
    let floor = 1e-9 * (1.0 + abs(guess));
    if !(step > floor) {
        step = floor;
    }
    step *= 1.0 + 1e-9;
    // expand until the residual changes sign (slopes kept: the refinement starts at a
    // bracket end without evaluating it again)
    let (mut lo, mut hi, mut r_lo, mut r_hi, d_lo, d_hi);
    let mut inner = guess;
    let mut r_inner = r0;
    let mut d_inner = d0;
    let mut n = 0;
    loop {
        let outer = inner + dir * step;
        if !outer.is_finite() {
            return None;
        }
        let (y_outer, d_outer) = f(outer);
        let r_outer = y_outer - target;
        if !r_outer.is_finite() {
            return None;
        }
        if abs(r_outer) <= resolution {
            return Some(outer);
        }
        if (r_outer > 0.0) != (r_inner > 0.0) {
            if dir > 0.0 {
                (lo, r_lo, d_lo) = (inner, r_inner, d_inner);
                (hi, r_hi, d_hi) = (outer, r_outer, d_outer);
            } else {
                (lo, r_lo, d_lo) = (outer, r_outer, d_outer);
                (hi, r_hi, d_hi) = (inner, r_inner, d_inner);
            }
            break;
        }
        inner = outer;
        r_inner = r_outer;
        d_inner = d_outer;
        step *= 2.0;
        n += 1;
        if n > MAX_EXPANSIONS {
            return None;
        }
    }
    // refine inside [lo, hi], r_lo < 0 < r_hi
    let (mut x, mut r, mut d) = if abs(r_lo) < abs(r_hi) { (lo, r_lo, d_lo) } else { (hi, r_hi, d_hi) };
    // bracket widths one and two iterations ago: Newton must at least halve the bracket
    // every two steps, else it is cycling (e.g. across the inflexion of an S-shaped curve,
    // where it can alternate between two points forever) and we bisect
    let (mut width_1, mut width_2) = (hi - lo, f64::INFINITY);
    for iteration in 0..MAX_REFINEMENTS {
        if iteration > 0 {
            let (y, slope) = f(x);
            r = y - target;
            d = slope;
        }
        if abs(r) <= resolution {
            return Some(x);
        }
        if r < 0.0 {
            lo = x;
            r_lo = r;
        } else {
            hi = x;
            r_hi = r;
        }
        let width = hi - lo;
        let slow = width > 0.5 * width_2;
        width_2 = width_1;
        width_1 = width;
        let mut next = if d > 0.0 && d.is_finite() { x - r / d } else { f64::NAN };
        if slow || !(next > lo && next < hi) {
            next = lo + 0.5 * (hi - lo);
        }
        if next <= lo || next >= hi {
            break; // lo and hi are adjacent floats
        }
        x = next;
    }
    Some(if abs(r_lo) <= abs(r_hi) { lo } else { hi })
}

/// Per-sample inverse of one sample: find `v` with `model(v) = y_desired` from the frozen
/// state, advance the state with it, return `v`. `guess` is usually the previous input.
/// `k` only labels the error.
pub fn inverse_step<M: Invertible + ?Sized>(
    model: &M,
    state: &mut [f64],
    y_desired: f64,
    guess: f64,
    k: usize,
) -> Result<f64, ModelError> {
    let st: &[f64] = state;
    let v = solve_increasing(|v| model.trial(st, v), y_desired, guess).ok_or(ModelError::Unreachable(k, y_desired))?;
    model.step(state, v);
    Ok(v)
}

/// Invert a whole record: `v[k]` such that the model driven by `v` outputs `y_desired[k]`.
/// `guess` seeds the first sample (0 for a relaxed state).
pub fn inverse_simulate<M: Invertible + ?Sized>(
    model: &M,
    state: &mut [f64],
    y_desired: &[f64],
    v_out: &mut [f64],
    mut guess: f64,
) -> Result<(), ModelError> {
    for (k, (&yd, v)) in y_desired.iter().zip(v_out.iter_mut()).enumerate() {
        *v = inverse_step(model, state, yd, guess, k)?;
        guess = *v;
    }
    Ok(())
}
