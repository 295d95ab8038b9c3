//! Small dense matrices for discretizing linear dynamics (no allocation, no_std).
use crate::num::math::abs;

/// The dot product of two slices (over the shorter one's length), in four partial sums: the
/// additions of one running sum each wait for the one before, four sums do not (the MIMO
/// models' rows of 100+ states run about twice as fast); the rounding differs from a running
/// sum's in the last bits only.
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut s = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        s[0] += x[0] * y[0];
        s[1] += x[1] * y[1];
        s[2] += x[2] * y[2];
        s[3] += x[3] * y[3];
    }
    let mut total = (s[0] + s[1]) + (s[2] + s[3]);
    for (x, y) in ra.iter().zip(rb) {
        total += x * y;
    }
    total
}

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

    #[test]
    fn dot_of_every_length_and_of_unequal_slices() {
        // integers: every partial sum is exact, so the order of the additions cannot show
        for n in 0..11 {
            let a: [f64; 10] = core::array::from_fn(|i| (i + 1) as f64);
            let b: [f64; 10] = core::array::from_fn(|i| (2 * i) as f64 - 7.0);
            let want: f64 = (0..n.min(10)).map(|i| a[i] * b[i]).sum();
            assert_eq!(dot(&a[..n.min(10)], &b), want, "n = {n}");
        }
        assert_eq!(dot(&[], &[1.0]), 0.0);
        assert_eq!(dot(&[1.0, 2.0, 3.0, 4.0, 5.0], &[1.0, 1.0]), 3.0);
        // the four sums: 1e16 and -1e16 meet in one lane, the ones stay in the others (one
        // running sum loses each 1 added to 1e16 and gives 0)
        let a = [1e16, 1.0, 1.0, 1.0, -1e16, 0.0, 0.0, 0.0];
        assert_eq!(dot(&a, &[1.0; 8]), 3.0);
        assert_eq!(a.iter().sum::<f64>(), 0.0);
    }
}
