//! Small dense matrices for discretizing linear dynamics (no allocation, no_std).
use crate::num::math::abs;

/// An `N x N` matrix, row-major.
pub type Mat<const N: usize> = [[f64; N]; N];

/// `a * b`.
pub fn matmul<const N: usize>(a: &Mat<N>, b: &Mat<N>) -> Mat<N> {
    let mut c = [[0.0; N]; N];
    for i in 0..N {
        for k in 0..N {
            let aik = a[i][k];
            for j in 0..N {
                c[i][j] += aik * b[k][j];
            }
        }
    }
    c
}

fn norm1<const N: usize>(a: &Mat<N>) -> f64 {
    let mut best = 0.0;
    for j in 0..N {
        let s: f64 = a.iter().map(|row| abs(row[j])).sum();
        if s > best {
            best = s;
        }
    }
    best
}

/// Matrix exponential `exp(a)` by scaling and squaring with a degree-18 Taylor series
/// (the scaled norm is at most 1/2, so the truncation error is below 1e-22 relative).
/// Used once per configuration, never in a step.
pub fn expm<const N: usize>(a: &Mat<N>) -> Mat<N> {
    let n1 = norm1(a);
    let mut s = 0u32;
    let mut scale = 1.0;
    while n1 * scale > 0.5 && s < 1000 {
        scale *= 0.5;
        s += 1;
    }
    let mut x = [[0.0; N]; N];
    for (x_row, a_row) in x.iter_mut().zip(a) {
        for (xij, &aij) in x_row.iter_mut().zip(a_row) {
            *xij = aij * scale;
        }
    }
    // Horner: I + X(I + X/2(I + X/3(...)))
    let mut e = [[0.0; N]; N];
    for (i, row) in e.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for k in (1..=18).rev() {
        let mut t = matmul(&x, &e);
        for (i, row) in t.iter_mut().enumerate() {
            for tij in row.iter_mut() {
                *tij /= k as f64;
            }
            row[i] += 1.0;
        }
        e = t;
    }
    for _ in 0..s {
        e = matmul(&e, &e);
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponential_of_a_rotation_and_a_decay() {
        let w = 3.0;
        let e = expm(&[[0.0, w], [-w, 0.0]]);
        assert!((e[0][0] - libm::cos(w)).abs() < 1e-14 && (e[0][1] - libm::sin(w)).abs() < 1e-14);
        let d = expm(&[[-50.0]]);
        assert!((d[0][0] - libm::exp(-50.0)).abs() < 1e-30);
    }
}
