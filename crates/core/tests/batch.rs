//! Lane kernels (`batch::pi_lanes`) are bit-identical to `Pi::step` lane by lane.
mod common;

use common::*;
use piezohyst_core::batch::{pi_lanes, LANES};
use piezohyst_core::pi::Pi;
use proptest::prelude::*;

/// Parameters of `L` PI models with `n` operators each: (p0, thresholds, weights) per lane.
type Lanes = Vec<(f64, Vec<f64>, Vec<f64>)>;

fn lanes_strategy(l: usize, n: usize) -> impl Strategy<Value = Lanes> {
    prop::collection::vec(
        (-1.0..2.0f64, 0.0..0.3f64, prop::collection::vec(0.01..0.5f64, n), prop::collection::vec(-1.0..1.0f64, n))
            .prop_map(|(p0, r0, inc, w)| (p0, thresholds_from(r0, &inc), w)),
        l,
    )
}

/// Run the lane kernel for `L` lanes and compare each lane with a `Pi` run alone.
fn check<const L: usize>(lanes: &Lanes, v: &[f64]) -> Result<(), TestCaseError> {
    let n = lanes[0].1.len();
    let mut p0 = [0.0; L];
    let mut r = vec![[0.0; L]; n];
    let mut w = vec![[0.0; L]; n];
    for (l, (p, rr, ww)) in lanes.iter().enumerate() {
        p0[l] = *p;
        for i in 0..n {
            r[i][l] = rr[i];
            w[i][l] = ww[i];
        }
    }
    let mut z = vec![[0.0; L]; n];
    // one spare output row: it must stay untouched
    let mut y = vec![[f64::NAN; L]; v.len() + 1];
    pi_lanes::<L>(&p0, &r, &w, &mut z, v, &mut y);
    for (l, (p, rr, ww)) in lanes.iter().enumerate() {
        let m = Pi::new(*p, rr, ww).unwrap();
        let (ys, st) = simulate(&m, v);
        for k in 0..v.len() {
            prop_assert!(y[k][l].to_bits() == ys[k].to_bits(), "lane {} sample {}: {:e} vs {:e}", l, k, y[k][l], ys[k]);
        }
        for i in 0..n {
            prop_assert!(z[i][l].to_bits() == st[i].to_bits(), "lane {} state {}", l, i);
        }
        prop_assert!(y[v.len()][l].is_nan(), "spare output row was written");
    }
    Ok(())
}

proptest! {
    #![proptest_config(cfg(64))]

    #[test]
    fn pi_lanes_8_bit_identical(n in 0usize..10, seed in any::<u64>(), v in input_strategy(3.0, 0..200)) {
        let lanes = lanes_for(LANES, n, seed);
        check::<LANES>(&lanes, &v)?;
    }

    #[test]
    fn pi_lanes_16_and_32_bit_identical(n in 1usize..10, seed in any::<u64>(), v in input_strategy(3.0, 1..150)) {
        check::<16>(&lanes_for(16, n, seed), &v)?;
        check::<32>(&lanes_for(32, n, seed ^ 0x5555), &v)?;
    }

    #[test]
    fn pi_lanes_random_strategy(lanes in lanes_strategy(LANES, 5), v in input_strategy(3.0, 1..150)) {
        check::<LANES>(&lanes, &v)?;
    }
}

/// Deterministic lane parameters from a seed (keeps the lane count generic).
fn lanes_for(l: usize, n: usize, mut seed: u64) -> Lanes {
    let mut next = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..l)
        .map(|_| {
            let p0 = -1.0 + 3.0 * next();
            let inc: Vec<f64> = (0..n).map(|_| 0.01 + 0.5 * next()).collect();
            let r = thresholds_from(0.3 * next(), &inc);
            let w = (0..n).map(|_| -1.0 + 2.0 * next()).collect();
            (p0, r, w)
        })
        .collect()
}

/// `batch::pi_group` (the grouped rows of the batch engine, moved from the Python binding)
/// gives each row's outputs and sum of squared errors bit for bit as a `Pi` run alone,
/// for unrolled (n <= 12) and general (n > 12) operator counts and partial groups.
#[test]
fn pi_group_is_bit_identical_to_single_runs() {
    use piezohyst_core::batch::{pi_group, MAX_FIXED_OPERATORS};
    use piezohyst_core::Hysteresis;
    const L: usize = 8;
    let v: Vec<f64> = (0..203).map(|k| (k as f64 * 0.07).sin() * (1.0 + 0.01 * k as f64)).collect();
    let target: Vec<f64> = v.iter().map(|x| 0.5 * x).collect();
    for &(n, used) in &[(3usize, 8usize), (9, 5), (MAX_FIXED_OPERATORS + 3, 8), (20, 1)] {
        let rows: Vec<Vec<f64>> = (0..used)
            .map(|j| {
                let mut row = vec![0.8 + 0.01 * j as f64];
                row.extend((0..n).map(|i| 0.05 * i as f64));
                row.extend((0..n).map(|i| 0.3 / (1.0 + i as f64 + j as f64)));
                row
            })
            .collect();
        let refs: Vec<&[f64]> = rows.iter().map(|r| r.as_slice()).collect();
        let mut scratch = vec![[0.0; L]; 3 * n];
        let mut out = vec![0.0; used * v.len()];
        pi_group::<L>(n, &refs, &v, &mut out, None, &mut scratch);
        let mut sse = vec![0.0; used];
        pi_group::<L>(n, &refs, &v, &mut sse, Some(&target), &mut scratch);
        for (j, row) in rows.iter().enumerate() {
            let pi = Pi::new(row[0], &row[1..1 + n], &row[1 + n..]).unwrap();
            let mut st = vec![0.0; n];
            let mut e2 = 0.0;
            for (k, &vk) in v.iter().enumerate() {
                let y = pi.step(&mut st, vk);
                assert_eq!(y.to_bits(), out[j * v.len() + k].to_bits(), "n {n} row {j} sample {k}");
                let e = y - target[k];
                e2 += e * e;
            }
            assert_eq!(e2.to_bits(), sse[j].to_bits(), "n {n} row {j} sse");
        }
    }
}
