//! Discretized Preisach model (docs/spec.md §2.7) against an independent brute-force relay
//! simulation, an independent Everett integral, wiping-out, congruency of minor loops,
//! saturation and the bounded-memory fallback.
mod common;

use common::*;
use piezohyst_core::preisach::{cell_count, cell_index, row_prefix, Preisach, MAX_MEMORY};
use piezohyst_core::Hysteresis;
use proptest::prelude::*;

/// Owned parameters of a Preisach model.
#[derive(Debug, Clone)]
struct P {
    lo: f64,
    hi: f64,
    levels: usize,
    w: Vec<f64>,
    pre: Vec<f64>,
    offset: f64,
    slope: f64,
}

impl P {
    fn new(lo: f64, hi: f64, levels: usize, w: Vec<f64>, offset: f64, slope: f64) -> Self {
        let mut pre = vec![0.0; w.len()];
        row_prefix(levels, &w, &mut pre);
        P { lo, hi, levels, w, pre, offset, slope }
    }
    fn model(&self, memory: usize) -> Preisach<'_> {
        Preisach {
            lo: self.lo,
            hi: self.hi,
            levels: self.levels,
            weights: &self.w,
            prefix: &self.pre,
            offset: self.offset,
            slope: self.slope,
            memory,
        }
        .validated()
        .unwrap()
    }
    fn total(&self) -> f64 {
        self.w.iter().sum()
    }
}

fn params(max_levels: usize) -> impl Strategy<Value = P> {
    (1..=max_levels).prop_flat_map(|levels| {
        (
            prop::collection::vec(prop_oneof![1 => Just(0.0), 3 => 0.0..1.0f64], cell_count(levels)),
            -0.5..0.5f64,
            0.0..0.5f64,
        )
            .prop_map(move |(w, offset, slope)| P::new(-1.0, 1.0, levels, w, offset, slope))
    })
}

/// Brute-force relays on a grid `K` times finer than the cells, with inputs restricted to
/// grid points: then every sub-cell switches as one, and the output is exact.
struct Relays {
    g: usize, // grid size L*K
    lo: f64,
    delta: f64,
    up: Vec<bool>, // sub-cell (p, q), q <= p, row-major like cell_index
    mass: Vec<f64>,
}

impl Relays {
    fn new(p: &P, k: usize) -> Self {
        let g = p.levels * k;
        let mut mass = vec![0.0; g * (g + 1) / 2];
        for pa in 0..g {
            for qb in 0..=pa {
                let (i, j) = (pa / k, qb / k);
                let w = p.w[cell_index(i, j)];
                let kk = (k * k) as f64;
                mass[cell_index(pa, qb)] = if i > j {
                    w / kk
                } else if pa > qb {
                    2.0 * w / kk
                } else {
                    w / kk
                };
            }
        }
        Relays { g, lo: p.lo, delta: (p.hi - p.lo) / g as f64, up: vec![false; mass.len()], mass }
    }
    /// Apply the grid input `j` (input value lo + j*delta); return the relay mass that is up.
    fn apply(&mut self, j: i64) {
        for pa in 0..self.g {
            for qb in 0..=pa {
                let c = cell_index(pa, qb);
                if j >= (pa + 1) as i64 {
                    self.up[c] = true; // v >= upper edge of the alpha interval
                } else if j <= qb as i64 {
                    self.up[c] = false; // v <= lower edge of the beta interval
                }
            }
        }
    }
    fn up_mass(&self) -> f64 {
        self.up.iter().zip(&self.mass).filter(|(u, _)| **u).map(|(_, m)| m).sum()
    }
    fn value(&self, j: i64) -> f64 {
        self.lo + self.delta * j as f64
    }
}

/// Independent Everett integral: exact area of each cell (square or diagonal triangle) cut
/// by `b <= beta <= alpha <= a`, times the cell's density.
fn everett_ref(p: &P, a: f64, b: f64) -> f64 {
    let h = (p.hi - p.lo) / p.levels as f64;
    let mut mass = 0.0;
    for i in 0..p.levels {
        for j in 0..=i {
            let w = p.w[cell_index(i, j)];
            let (a0, a1) = (p.lo + i as f64 * h, p.lo + (i + 1) as f64 * h);
            let (b0, b1) = (p.lo + j as f64 * h, p.lo + (j + 1) as f64 * h);
            if i > j {
                let da = (a1.min(a) - a0).max(0.0);
                let db = (b1 - b0.max(b)).max(0.0);
                mass += w * da * db / (h * h);
            } else {
                let s = (a1.min(a) - b0.max(b)).max(0.0);
                mass += w * s * s / (h * h);
            }
        }
    }
    mass
}

proptest! {
    #![proptest_config(cfg(256))]

    /// The model equals brute-force relays on grid-aligned inputs (fractional cell positions
    /// 1/K included), including inputs beyond [lo, hi].
    #[test]
    fn matches_brute_force_relays(
        p in params(6),
        k in prop_oneof![Just(1usize), Just(2), Just(3), Just(4)],
        js in prop::collection::vec(-3i64..30, 1..120),
    ) {
        let mut relays = Relays::new(&p, k);
        let g = relays.g as i64;
        let m = p.model(MAX_MEMORY);
        let mut st = vec![0.0; m.state_len()];
        m.reset(&mut st);
        for (n, &j0) in js.iter().enumerate() {
            let j = j0.rem_euclid(g + 7) - 3; // in [-3, g + 3]
            let v = relays.value(j);
            relays.apply(j);
            let want = p.offset + p.slope * v + relays.up_mass();
            let got = m.step(&mut st, v);
            prop_assert!((got - want).abs() <= 1e-12 * (1.0 + p.total()), "sample {}: v={} model {} relays {}", n, v, got, want);
        }
    }

    /// Everett integral against the independent cell-by-cell area computation.
    #[test]
    fn everett_matches_area_computation(p in params(8), a in -1.3..1.3f64, b in -1.3..1.3f64) {
        let m = p.model(2);
        let got = m.everett(a, b);
        let want = everett_ref(&p, a, b);
        prop_assert!((got - want).abs() <= 1e-12 * (1.0 + p.total()), "E({}, {}) = {} vs {}", a, b, got, want);
        prop_assert!(got >= 0.0);
        // E(hi, lo) is the total mass
        prop_assert!((m.everett(1.0, -1.0) - p.total()).abs() <= 1e-12 * (1.0 + p.total()));
    }

    /// Wiping-out: nested minor loops inside [v_p, M] followed by an input above M leave no
    /// trace: state and all later outputs equal the path that went from v_p straight above M.
    #[test]
    fn wiping_out(
        p in params(8),
        prefix in input_strategy(1.2, 1..30),
        rise in 0.05..1.0f64,
        loops in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64), 1..12),
        above in 0.0..0.5f64,
        suffix in input_strategy(1.3, 0..30),
    ) {
        let m = p.model(MAX_MEMORY);
        let vp = *prefix.last().unwrap();
        let big_m = vp + rise;
        let m_new = big_m + above + 1e-3;
        let mut a = vec![big_m];
        let (mut lo, mut hi) = (vp, big_m);
        for &(u, t) in &loops {
            let mn = lo + (hi - lo) * u * 0.9;
            let mx = mn + (hi - mn) * (0.1 + 0.9 * t);
            a.push(mn);
            a.push(mx);
            lo = mn;
            hi = mx;
        }
        let mut path_a = prefix.clone();
        path_a.extend_from_slice(&a);
        path_a.push(m_new);
        let mut path_b = prefix.clone();
        path_b.push(m_new);
        let (_, sa) = simulate(&m, &path_a);
        let (_, sb) = simulate(&m, &path_b);
        // the state (previous input, stack length, stored extrema) is identical
        let len = sb[1] as usize;
        prop_assert_eq!(sa[1], sb[1]);
        prop_bits_eq(&sa[..2 + len], &sb[..2 + len], "state after exceeding M")?;
        path_a.extend_from_slice(&suffix);
        path_b.extend_from_slice(&suffix);
        let (ya, _) = simulate(&m, &path_a);
        let (yb, _) = simulate(&m, &path_b);
        let tail = suffix.len() + 1;
        prop_bits_eq(&ya[ya.len() - tail..], &yb[yb.len() - tail..], "outputs after exceeding M")?;
    }

    /// Congruency: after two different histories that both fall from above v2 to v1, the
    /// output increments along the same back-and-forth path between v1 and v2 coincide.
    #[test]
    fn congruent_minor_loops(
        p in params(8),
        h1 in input_strategy(1.3, 0..30),
        h2 in input_strategy(1.3, 0..30),
        v1 in -1.1..0.9f64,
        width in 0.05..1.0f64,
        top1 in 0.0..0.5f64,
        top2 in 0.0..0.5f64,
        ts in prop::collection::vec(0.0..1.0f64, 1..20),
    ) {
        let v2 = v1 + width;
        // a back-and-forth path inside [v1, v2]: up through sorted points to v2, then down
        let mut up: Vec<f64> = ts.iter().map(|t| v1 + t * width).collect();
        up.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let mut lp: Vec<f64> = up.clone();
        lp.push(v2);
        lp.extend(up.iter().rev());
        lp.push(v1);
        let m = p.model(MAX_MEMORY);
        let run = |h: &[f64], top: f64| {
            let mut path = h.to_vec();
            path.push(v2 + top);
            path.push(v1);
            path.extend_from_slice(&lp);
            let (y, _) = simulate(&m, &path);
            let base = y[h.len() + 1];
            y[h.len() + 2..].iter().map(|x| x - base).collect::<Vec<f64>>()
        };
        let d1 = run(&h1, top1);
        let d2 = run(&h2, top2);
        prop_assert!(max_diff(&d1, &d2) <= 1e-12 * (1.0 + p.total()), "loop increments differ by {:e}", max_diff(&d1, &d2));
        // the loop closes: back at v1 the increment is zero
        prop_assert!(d1.last().unwrap().abs() <= 1e-12 * (1.0 + p.total()));
        // and the rising branch increment at v2 is the Everett integral E(v2, v1) + slope*width
        let at_v2 = d1[up.len()];
        let want = m.everett(v2, v1) + p.slope * width;
        prop_assert!((at_v2 - want).abs() <= 1e-12 * (1.0 + p.total()));
    }

    /// With a shallow memory, paths whose stack never exceeds it give the same output as the
    /// full memory; deeper ones are approximated but the output stays within the physical
    /// range offset + slope*v + [0, total mass].
    #[test]
    fn bounded_memory(p in params(8), v in input_strategy(1.3, 1..200), memory in 2usize..8) {
        let full = p.model(MAX_MEMORY);
        let short = p.model(memory);
        let mut sf = vec![0.0; full.state_len()];
        let mut ss = vec![0.0; short.state_len()];
        full.reset(&mut sf);
        short.reset(&mut ss);
        let mut overflowed = false;
        for &x in &v {
            let yf = full.step(&mut sf, x);
            let ys = short.step(&mut ss, x);
            prop_assert!(ss[1] as usize <= memory);
            overflowed |= sf[1] as usize > memory;
            if !overflowed {
                prop_assert_eq!(yf.to_bits(), ys.to_bits());
            }
            let base = p.offset + p.slope * x;
            prop_assert!(ys >= base - 1e-12 && ys <= base + p.total() * (1.0 + 1e-12) + 1e-12);
        }
    }
}

#[test]
fn relaxed_state_and_saturation() {
    let levels = 3;
    let w: Vec<f64> = (0..cell_count(levels)).map(|i| 0.1 + 0.05 * i as f64).collect();
    let p = P::new(-2.0, 2.0, levels, w, 0.3, 0.2);
    let m = p.model(16);
    let mut st = vec![7.0; m.state_len()];
    m.reset(&mut st);
    assert_eq!(st[0], -2.0);
    assert!(st[1..].iter().all(|&x| x == 0.0));
    // below lo: all relays down
    assert_eq!(m.step(&mut st, -3.0), 0.3 + 0.2 * -3.0);
    // above hi: all relays up
    let y = m.step(&mut st, 2.5);
    assert!((y - (0.3 + 0.2 * 2.5 + p.total())).abs() < 1e-14);
    assert_eq!(st[1], 0.0, "rising past every extremum leaves an empty stack");
    // falling back inside: one stored maximum, output loses E(hi, v)
    let y = m.step(&mut st, 0.5);
    assert_eq!(st[1], 1.0);
    assert_eq!(st[2], 2.5);
    assert!((y - (0.3 + 0.2 * 0.5 + p.total() - m.everett(2.0, 0.5))).abs() < 1e-14);
    // negative saturation erases everything
    m.step(&mut st, -2.0);
    assert_eq!(st[1], 0.0);
    // the first rise from the relaxed state is E(v, lo)
    m.reset(&mut st);
    let y = m.step(&mut st, 0.7);
    assert!((y - (0.3 + 0.2 * 0.7 + m.everett(0.7, -2.0))).abs() < 1e-14);
    assert!(m.everett(0.7, -2.0) > 0.0);
}

#[test]
fn construction_errors() {
    use piezohyst_core::ModelError;
    let w = vec![0.1; cell_count(3)];
    let mut pre = vec![0.0; w.len()];
    row_prefix(3, &w, &mut pre);
    let valid =
        Preisach { lo: -1.0, hi: 1.0, levels: 3, weights: &w, prefix: &pre, offset: 0.0, slope: 0.1, memory: 8 };
    assert!(valid.validated().is_ok());
    assert_eq!(Preisach { lo: 1.0, ..valid }.validated().err(), Some(ModelError::NotIncreasing("input_range", 1, 1.0)));
    assert_eq!(Preisach { levels: 0, ..valid }.validated().err(), Some(ModelError::Structure("levels", 0)));
    assert_eq!(Preisach { memory: 1, ..valid }.validated().err(), Some(ModelError::Structure("memory", 1)));
    assert_eq!(
        Preisach { memory: MAX_MEMORY + 1, ..valid }.validated().err(),
        Some(ModelError::Structure("memory", MAX_MEMORY + 1))
    );
    assert_eq!(Preisach { levels: 4, ..valid }.validated().err(), Some(ModelError::Length("weights", 10, 6)));
    assert_eq!(Preisach { prefix: &pre[..5], ..valid }.validated().err(), Some(ModelError::Length("prefix", 6, 5)));
    let mut wn = w.clone();
    wn[4] = -0.01;
    assert_eq!(Preisach { weights: &wn, ..valid }.validated().err(), Some(ModelError::Negative("weights", 4, -0.01)));
    assert_eq!(
        Preisach { slope: -0.1, ..valid }.validated().err(),
        Some(ModelError::Negative("slope", usize::MAX, -0.1))
    );
    wn[4] = f64::NAN;
    assert!(
        matches!(Preisach { weights: &wn, ..valid }.validated(), Err(ModelError::NotFinite("weights", 4, x)) if x.is_nan())
    );
}

/// Regression: with the stack full, a reversal whose new extremum is wiped out by the same
/// sample must not make the model forget a stored loop (it needs no slot).
#[test]
fn full_memory_reversal_wiped_at_once_forgets_nothing() {
    let p = P::new(-1.0, 1.0, 2, vec![0.4, 0.3, 0.5], 0.0, 0.0);
    let full = p.model(MAX_MEMORY);
    let short = p.model(3);
    // stack after the 4th sample: [1.2, -0.7, 0.0] (full for memory 3); the 5th sample
    // reverses at -0.2 and passes 0.0 at once, so the stack becomes [1.2, -0.7]
    let v = [1.2, -0.7, 0.0, -0.2, 0.1, -0.5];
    let (yf, sf) = simulate(&full, &v);
    let (ys, ss) = simulate(&short, &v);
    assert_bits_eq(&ys, &yf, "memory 3 vs full memory");
    assert_eq!(sf[1], 3.0);
    assert_bits_eq(&ss[..5], &sf[..5], "state");
}
