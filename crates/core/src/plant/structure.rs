//! A stage with structural freedom (issue 19): more modes than the stack's own, any
//! hysteresis law of the crate driven by the amplifier voltage in place of the CEMF law, and
//! a DAC of finite resolution in front of the amplifier. The stage kernel
//! ([`crate::plant::stage`]) runs them through its [`Extra`] hooks, sub-step by sub-step,
//! with the same exactness as its own mode; the plain stage ([`crate::plant::stage::NoExtra`])
//! is untouched by them.
//!
//! **Modes.** The stack's mode is the stage's `m x'' + b x' + k x = F`. Each added mode `i`
//! (frequency `f_i`, damping ratio `zeta_i`, relative gain `g_i`) is driven by the same force,
//! with the same static deflection:
//!
//! ```text
//! q_i'' + 2 zeta_i w_i q_i' + w_i^2 q_i = w_i^2 F / k
//! position = (x + sum_i g_i q_i) / (1 + sum_i g_i)
//! ```
//!
//! so the static gain is the stage's, and `g_i` is the mode's share of the static
//! deflection relative to the stack's mode (a negative `g_i`, with `1 + sum g > 0`, is a mode
//! in anti-phase at a non-collocated sensor). The stack's displacement `x` (what the CEMF's
//! charge sees) is the first mode's; the position a sensor reads is the modal sum. Each
//! mode is discretized exactly over a sub-step like the stack's mode: with the amplifier
//! (command held) while it is not slew-limited, the rest of the force first-order held.
//!
//! **Voltage-driven hysteresis.** A hysteresis model `H` (input V, output m; any family of
//! [`crate::spec`], e.g. one identified from a record) replaces the CEMF law: the stage's
//! quasi-static position is `H(Va)`, i.e. the hysteresis voltage is
//! `Vh = Va - (k / Tem) H(Va)` in the stage's force `Tem (Va - Vh + Vcr + e2 Va^2)`; creep and
//! electrostriction stay the stage's own. `H` is stepped once per controller period with the
//! period's end voltage (its sample time is the loop's); inside the period its output is the
//! trial at the sub-step's voltage (exact for the rate-independent families on the
//! amplifier's monotone path).
//!
//! **DAC.** The command is rounded to the nearest code `amp_min + j step` before the
//! amplifier (round half to even).
use crate::error::{check_scalar, ModelError};
use crate::hysteresis::Invertible;
use crate::num::math::exp;
use crate::plant::stage::{Discrete, Extra, Stage, SubStep, LEVELS};

/// Most modes a stage can add.
pub const MAX_MODES: usize = 4;

/// One added mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency, Hz (> 0).
    pub frequency: f64,
    /// Damping ratio (>= 0).
    pub damping_ratio: f64,
    /// Share of the static deflection relative to the stack's mode.
    pub gain: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct ModeLevel {
    /// `[q, q']`, forcing `r d` (the stack's forcing `d` scaled by `r = w_i^2 m / k`).
    mech: Discrete<2>,
    /// `[Va, q, q']` with the amplifier (command held), forcing `r d`.
    amp_mech: Discrete<3>,
}

/// The added modes of a stage, discretized for its sub-step lengths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Modes {
    n: usize,
    gains: [f64; MAX_MODES],
    /// `1 / (1 + sum g)`
    scale: f64,
    levels: [[ModeLevel; MAX_MODES]; LEVELS],
}

impl Modes {
    /// No added mode.
    pub fn none(stage: &Stage) -> Self {
        Self::new(stage, &[]).expect("no mode is valid")
    }

    /// Validate the modes and discretize them for `stage`'s sub-steps.
    pub fn new(stage: &Stage, modes: &[Mode]) -> Result<Self, ModelError> {
        if modes.len() > MAX_MODES {
            return Err(ModelError::Structure("modes", modes.len()));
        }
        let p = &stage.params;
        let (m, k) = (p.mass, p.stiffness);
        let mut gains = [0.0; MAX_MODES];
        let mut sum = 0.0;
        for (i, md) in modes.iter().enumerate() {
            check_scalar("mode frequency", md.frequency)?;
            check_scalar("mode damping_ratio", md.damping_ratio)?;
            check_scalar("mode gain", md.gain)?;
            if !(md.frequency > 0.0) {
                return Err(ModelError::NotPositive("mode frequency", i, md.frequency));
            }
            if md.damping_ratio < 0.0 {
                return Err(ModelError::Negative("mode damping_ratio", i, md.damping_ratio));
            }
            gains[i] = md.gain;
            sum += md.gain;
        }
        if !(1.0 + sum > 0.0) {
            return Err(ModelError::NotPositive("1 + sum of the mode gains", usize::MAX, 1.0 + sum));
        }
        let zero = ModeLevel {
            mech: Discrete::new::<5>(&[[0.0; 2]; 2], &[0.0; 2], &[0.0; 2], 1.0),
            amp_mech: Discrete::new::<6>(&[[0.0; 3]; 3], &[0.0; 3], &[0.0; 3], 1.0),
        };
        let mut levels = [[zero; MAX_MODES]; LEVELS];
        let tau = stage.amplifier_tau();
        for (j, level) in levels.iter_mut().enumerate() {
            let h = stage.level_h(j);
            for (i, md) in modes.iter().enumerate() {
                let w = 2.0 * core::f64::consts::PI * md.frequency;
                let (w2, c) = (w * w, 2.0 * md.damping_ratio * w);
                let r = w2 * m / k;
                let mech = Discrete::new::<5>(&[[0.0, 1.0], [-w2, -c]], &[0.0, 0.0], &[0.0, r], h);
                let amp_mech = match tau {
                    None => zero.amp_mech,
                    Some(t) => {
                        let a = [[-1.0 / t, 0.0, 0.0], [0.0, 0.0, 1.0], [r * p.tem / m, -w2, -c]];
                        Discrete::new::<6>(&a, &[1.0 / t, 0.0, 0.0], &[0.0, 0.0, r], h)
                    }
                };
                level[i] = ModeLevel { mech, amp_mech };
            }
        }
        Ok(Modes { n: modes.len(), gains, scale: 1.0 / (1.0 + sum), levels })
    }

    /// Number of added modes.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// State slots: `[q_i, q_i']` per mode.
    pub fn state_len(&self) -> usize {
        2 * self.n
    }

    /// At rest at the stack's displacement `x` (every mode at its static deflection).
    pub fn reset(&self, state: &mut [f64], x: f64) {
        for i in 0..self.n {
            state[2 * i] = x;
            state[2 * i + 1] = 0.0;
        }
    }

    /// The modal sum the sensor sees.
    #[inline(always)]
    pub fn position(&self, state: &[f64], x: f64) -> f64 {
        if self.n == 0 {
            return x;
        }
        let mut y = x;
        for i in 0..self.n {
            y += self.gains[i] * state[2 * i];
        }
        self.scale * y
    }

    #[inline(always)]
    fn substep(&self, state: &mut [f64], step: &SubStep) {
        let SubStep { level, va0, u, d0, d1, with_va } = *step;
        for (i, lv) in self.levels[level][..self.n].iter().enumerate() {
            let (q, dq) = (state[2 * i], state[2 * i + 1]);
            let (q1, dq1) = if with_va {
                let z = lv.mech.apply(&[q, dq], 0.0, d0, d1);
                (z[0], z[1])
            } else {
                let z = lv.amp_mech.apply(&[va0, q, dq], u, d0, d1);
                (z[1], z[2])
            };
            state[2 * i] = q1;
            state[2 * i + 1] = dq1;
        }
    }
}

/// A stage's structure: added modes, a voltage-driven hysteresis law `H` (or none: the
/// stage's CEMF law), a DAC step (0: none). The state is a caller's buffer of
/// [`Structure::state_len`] slots: the modes' `[q, q']`, then the law's state.
#[derive(Debug, Clone, Copy)]
pub struct Structure<H> {
    /// Added modes.
    pub modes: Modes,
    /// Voltage-driven hysteresis (input V, output m), replacing the CEMF law.
    pub hysteresis: Option<H>,
    /// `k / Tem`, V/m.
    volts_per_metre: f64,
    /// DAC step, V (0: none).
    dac_step: f64,
    /// DAC code 0, V (the amplifier's lower limit).
    dac_origin: f64,
    /// Thermal drift (none: `None`).
    drift: Option<Drift>,
    /// Control period, s (the drift's clock).
    ts: f64,
}

/// Thermal drift of the stage's structure after a temperature step at the run's start:
/// `y = (1 + gain s(t)) x + offset s(t)`, `s(t) = 1 - exp(-t / tau)`, on the position the
/// sensor sees (and the stage has): a slow displacement and a slow change of the stroke.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drift {
    /// Final additive displacement, m.
    pub offset: f64,
    /// Final relative gain change.
    pub gain: f64,
    /// Time constant, s (> 0).
    pub tau: f64,
}

impl Drift {
    /// Validate.
    pub fn new(offset: f64, gain: f64, tau: f64) -> Result<Self, ModelError> {
        check_scalar("drift_offset", offset)?;
        check_scalar("drift_gain", gain)?;
        check_scalar("drift_tau", tau)?;
        if tau <= 0.0 {
            return Err(ModelError::NotPositive("drift_tau", usize::MAX, tau));
        }
        if gain <= -1.0 {
            return Err(ModelError::OutOfRange("drift_gain", usize::MAX, gain, -1.0, f64::INFINITY));
        }
        Ok(Drift { offset, gain, tau })
    }
    #[inline(always)]
    fn apply(&self, t: f64, y: f64) -> f64 {
        let s = 1.0 - exp(-t / self.tau);
        (1.0 + self.gain * s) * y + self.offset * s
    }
}

impl<H: Invertible> Structure<H> {
    /// Validate and build for `stage`.
    pub fn new(stage: &Stage, modes: &[Mode], hysteresis: Option<H>, dac_step: f64) -> Result<Self, ModelError> {
        check_scalar("dac_step", dac_step)?;
        if dac_step < 0.0 {
            return Err(ModelError::Negative("dac_step", usize::MAX, dac_step));
        }
        let p = &stage.params;
        Ok(Structure {
            modes: Modes::new(stage, modes)?,
            hysteresis,
            volts_per_metre: p.stiffness / p.tem,
            dac_step,
            dac_origin: p.amp_min,
            drift: None,
            ts: stage.ts,
        })
    }

    /// With thermal drift (one more state slot: the time since the run's start, s).
    pub fn with_drift(mut self, drift: Option<Drift>) -> Self {
        self.drift = drift;
        self
    }

    fn law_len(&self) -> usize {
        self.hysteresis.as_ref().map_or(0, |h| h.state_len())
    }

    /// Slots of the state.
    pub fn state_len(&self) -> usize {
        self.modes.state_len() + self.law_len() + usize::from(self.drift.is_some())
    }

    /// The state at rest with the stack at `x`: modes at their static deflection, the law
    /// relaxed.
    pub fn reset(&self, state: &mut [f64], x: f64) {
        let (m, rest) = state.split_at_mut(self.modes.state_len());
        let (h, clock) = rest.split_at_mut(self.law_len());
        self.modes.reset(m, x);
        if let Some(law) = &self.hysteresis {
            law.reset(h);
        }
        clock.fill(0.0);
    }

    /// Check a state from outside (length, finite, the law's own rules).
    pub fn check_state(&self, state: &[f64]) -> Result<(), ModelError> {
        crate::hysteresis::check_state_len(state, self.state_len())?;
        crate::error::check_finite("state", state)?;
        let n = self.modes.state_len();
        let l = self.law_len();
        if self.drift.is_some() && state[n + l] < 0.0 {
            return Err(ModelError::Negative("state (drift clock)", n + l, state[n + l]));
        }
        match &self.hysteresis {
            Some(law) => law.check_state(&state[n..n + l]).map_err(|e| crate::compensated::offset_slot(e, n)),
            None => Ok(()),
        }
    }

    /// The position the sensor sees for the stack at `x` and this structure state.
    pub fn position(&self, state: &[f64], x: f64) -> f64 {
        let y = self.modes.position(&state[..self.modes.state_len()], x);
        match &self.drift {
            Some(d) => d.apply(state[self.modes.state_len() + self.law_len()], y),
            None => y,
        }
    }

    /// The hooks for one run on `state` (see [`Extra`]).
    pub fn run<'s>(&'s self, state: &'s mut [f64]) -> StructureRun<'s, H> {
        let law_len = self.law_len();
        let (modes, rest) = state.split_at_mut(self.modes.state_len());
        let (hyst, clock) = rest.split_at_mut(law_len);
        StructureRun { s: self, modes, hyst, clock }
    }

    #[inline(always)]
    fn quantize(&self, u: f64) -> f64 {
        const SHIFT: f64 = 6755399441055744.0; // 1.5 * 2^52: round half to even
        if self.dac_step > 0.0 {
            let t = (u - self.dac_origin) / self.dac_step;
            let r = if crate::num::math::abs(t) < 2251799813685248.0 { (t + SHIFT) - SHIFT } else { t };
            self.dac_origin + r * self.dac_step
        } else {
            u
        }
    }
}

/// A [`Structure`] with its state, as the stage kernel's [`Extra`] hooks.
#[derive(Debug)]
pub struct StructureRun<'s, H> {
    s: &'s Structure<H>,
    modes: &'s mut [f64],
    hyst: &'s mut [f64],
    clock: &'s mut [f64],
}

impl<H: Invertible> Extra for StructureRun<'_, H> {
    const ACTIVE: bool = true;
    #[inline(always)]
    fn command(&mut self, u: f64) -> f64 {
        self.s.quantize(u)
    }
    #[inline(always)]
    fn input_vh(&mut self, va: f64) -> Option<f64> {
        self.s.hysteresis.as_ref().map(|law| va - self.s.volts_per_metre * law.trial(self.hyst, va).0)
    }
    #[inline(always)]
    fn end_period(&mut self, va: f64) {
        if let Some(law) = &self.s.hysteresis {
            law.step(self.hyst, va);
        }
        if let Some(t) = self.clock.first_mut() {
            *t += self.s.ts;
        }
    }
    #[inline(always)]
    fn substep(&mut self, step: &SubStep) {
        self.s.modes.substep(self.modes, step);
    }
    #[inline(always)]
    fn position(&self, x: f64) -> f64 {
        let y = self.s.modes.position(self.modes, x);
        match (&self.s.drift, self.clock.first()) {
            (Some(d), Some(&t)) => d.apply(t, y),
            _ => y,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hysteresis::Hysteresis;
    use crate::plant::stage::{HysteresisDrive, StageParams, StageState, MAX_CREEP};
    use crate::spec::Family;

    fn linear_params() -> StageParams {
        StageParams {
            mass: 0.0714,
            damping: 137.3,
            stiffness: 7.333e7,
            tem: 10.5,
            capacitance: 1.8e-6,
            hyst_alpha: 0.0,
            hyst_beta: 0.0,
            hyst_gamma: 0.0,
            hyst_drive: HysteresisDrive::Charge,
            electrostriction: 0.0,
            creep_taus: [1.0; MAX_CREEP],
            creep_weights: [0.0; MAX_CREEP],
            creep_terms: 0,
            amp_min: -20.0,
            amp_max: 150.0,
            amp_bandwidth: 3000.0,
            amp_slew: f64::INFINITY,
        }
    }

    /// A structure without modes, law or DAC changes nothing: the same bits as the plain
    /// stage, on the virtual stage (CEMF, creep, slew limit, refinement).
    #[test]
    fn empty_structure_is_the_plain_stage() {
        let stage = Stage::new(StageParams::virtual_stage(), 1e-4, 1, 0.05).unwrap();
        let s: Structure<crate::pi::Pi<'_>> = Structure::new(&stage, &[], None, 0.0).unwrap();
        let mut state = [0.0; 0];
        let (mut a, mut b) = (StageState::ZERO, StageState::ZERO);
        for k in 0..3000 {
            let u = 75.0 + 70.0 * libm::sin(k as f64 * 0.01) + if k % 500 < 250 { 5.0 } else { 0.0 };
            stage.advance(&mut a, u);
            stage.advance_with(&mut b, u, &mut s.run(&mut state));
            assert_eq!(a.to_array().map(f64::to_bits), b.to_array().map(f64::to_bits), "{k}");
        }
    }

    /// Thermal drift: the stack's motion unchanged (same bits), the position seen
    /// `(1 + gain s) x + offset s`, `s = 1 - exp(-t / tau)` with the clock at `k Ts` after `k`
    /// periods; bad drift parameters are refused.
    #[test]
    fn drift_moves_the_position_by_its_law() {
        let stage = Stage::new(StageParams::virtual_stage(), 1e-4, 1, 0.05).unwrap();
        let drift = Drift::new(0.3e-6, 0.02, 0.05).unwrap();
        let s: Structure<crate::pi::Pi<'_>> = Structure::new(&stage, &[], None, 0.0).unwrap().with_drift(Some(drift));
        assert_eq!(s.state_len(), 1);
        let mut state = [0.0; 1];
        s.reset(&mut state, 0.0);
        let (mut a, mut b) = (StageState::ZERO, StageState::ZERO);
        for k in 1..=2000 {
            stage.advance(&mut a, 60.0);
            stage.advance_with(&mut b, 60.0, &mut s.run(&mut state));
            assert_eq!(a.x.to_bits(), b.x.to_bits(), "{k}");
            let t = k as f64 * 1e-4;
            assert!((state[0] - t).abs() < 1e-12, "{k}");
            let sd = 1.0 - libm::exp(-t / 0.05);
            let want = (1.0 + 0.02 * sd) * a.x + 0.3e-6 * sd;
            assert!((s.position(&state, b.x) - want).abs() < 1e-18, "{k}");
        }
        assert!(Drift::new(0.0, 0.0, 0.0).is_err());
        assert!(Drift::new(0.0, -1.0, 1.0).is_err());
        assert!(Drift::new(f64::NAN, 0.0, 1.0).is_err());
        assert!(s.check_state(&[-1.0]).is_err());
    }

    /// A mode's steady sine response is its second-order frequency response (measured by
    /// simulation, against the analytic modal sum), and its static deflection the stack's.
    #[test]
    fn a_mode_adds_its_resonance_to_the_modal_sum() {
        let p = linear_params();
        let ts = 1e-5;
        let stage = Stage::new(p, ts, 1, 0.05).unwrap();
        let mode = Mode { frequency: 2000.0, damping_ratio: 0.02, gain: 0.5 };
        let s: Structure<crate::pi::Pi<'_>> = Structure::new(&stage, &[mode], None, 0.0).unwrap();
        let mut state = [0.0; 2];
        let mut st = StageState::ZERO;
        // static: 100 V held
        for _ in 0..100_000 {
            stage.advance_with(&mut st, 100.0, &mut s.run(&mut state));
        }
        let y = s.position(&state, st.x);
        let static_gain = p.tem / p.stiffness;
        assert!((y / (100.0 * static_gain) - 1.0).abs() < 1e-9, "{y}");
        // a 1800 Hz sine of 1 V: the analytic modal sum (amplifier, stack, mode)
        let f = 1800.0;
        let w = 2.0 * core::f64::consts::PI * f;
        let (mut re, mut im) = (0.0, 0.0);
        let n = 20_000; // 36 periods after 20_000 samples of settling
        for k in 0..2 * n {
            let t = k as f64 * ts;
            let u = 100.0 + libm::sin(w * t);
            stage.advance_with(&mut st, u, &mut s.run(&mut state));
            if k >= n {
                // position at the end of the period t + ts
                let y = s.position(&state, st.x) - 100.0 * static_gain;
                re += y * libm::cos(w * (t + ts));
                im += y * libm::sin(w * (t + ts));
            }
        }
        let scale = 2.0 / n as f64;
        let measured = libm::hypot(re * scale, im * scale);
        let amp = 1.0 / libm::hypot(1.0, w / (2.0 * core::f64::consts::PI * 3000.0));
        let mech = |wn: f64, z: f64| {
            let (a, b) = (wn * wn - w * w, 2.0 * z * wn * w);
            (wn * wn * a / (a * a + b * b), -wn * wn * b / (a * a + b * b))
        };
        let w1 = libm::sqrt(p.stiffness / p.mass);
        let z1 = p.damping / (2.0 * libm::sqrt(p.stiffness * p.mass));
        let (ar, ai) = mech(w1, z1);
        let (br, bi) = mech(2.0 * core::f64::consts::PI * 2000.0, 0.02);
        let (sr, si) = ((ar + 0.5 * br) / 1.5, (ai + 0.5 * bi) / 1.5);
        // the command is held over each sample: the ZOH's gain sinc(f ts)
        let zoh = libm::sin(w * ts / 2.0) / (w * ts / 2.0);
        let expected = static_gain * amp * libm::hypot(sr, si) * zoh;
        assert!((measured / expected - 1.0).abs() < 2e-3, "{measured:e} vs {expected:e}");
        // the resonance shows: near 2x the static gain at 1.8 kHz (1.33 without the mode)
        assert!(measured > 1.8 * static_gain, "{}", measured / static_gain);
    }

    /// A voltage-driven PI law: the slow position follows `H(Va)` (the law's hysteresis
    /// loop, not the CEMF's); a DAC of 1 V steps rounds the command.
    #[test]
    fn a_voltage_driven_law_and_a_dac() {
        let p = linear_params();
        let stage = Stage::new(p, 1e-4, 1, 0.05).unwrap();
        // PI: y = p0 v + sum w_i play_r_i(v), in metres
        let g = p.tem / p.stiffness;
        let row = [0.5 * g, 0.0, 20.0, 60.0, 0.3 * g, 0.2 * g, 0.1 * g];
        let fam = Family::Pi { n: 3, creep: 0 };
        let mut scratch = vec![0.0; fam.scratch_len()];
        let law = fam.build(&row, &mut scratch).unwrap();
        let s = Structure::new(&stage, &[], Some(law), 0.0).unwrap();
        let mut state = vec![0.0; s.state_len()];
        s.reset(&mut state, 0.0);
        let mut reference_state = vec![0.0; law.state_len()];
        law.reset(&mut reference_state);
        let mut st = StageState::ZERO;
        let mut worst: f64 = 0.0;
        let mut at75 = [0.0; 2];
        for k in 0..20_000 {
            // a 1 Hz full-range sine, slow against the amplifier and the 5 kHz mode
            let u = 75.0 - 75.0 * libm::cos(2.0 * core::f64::consts::PI * k as f64 * 1e-4);
            stage.advance_with(&mut st, u, &mut s.run(&mut state));
            let h = law.step(&mut reference_state, u);
            if k > 1000 {
                worst = worst.max((st.x - h).abs() / (150.0 * g));
            }
            if k == 12_500 || k == 17_500 {
                at75[usize::from(k == 17_500)] = st.x;
            }
        }
        // the amplifier's lag at 1 Hz: 2 pi 1 Hz 75 V x 53 us = 0.025 V, 2e-4 of the range
        assert!(worst < 5e-4, "{worst}");
        // a loop, not a line: rising and falling through 75 V differ by the plays' width
        assert!((at75[0] - at75[1]).abs() > 0.05 * 150.0 * g, "{at75:?}");
        // the DAC: 10.3 V held reaches H(10 V) (codes every 1 V from -20 V)
        let dac = Structure::new(&stage, &[], Some(law), 1.0).unwrap();
        let mut state = vec![0.0; dac.state_len()];
        dac.reset(&mut state, 0.0);
        let mut st = StageState::ZERO;
        for _ in 0..2000 {
            stage.advance_with(&mut st, 10.3, &mut dac.run(&mut state));
        }
        let mut fresh = vec![0.0; law.state_len()];
        law.reset(&mut fresh);
        let h10 = law.step(&mut fresh, 10.0);
        assert!((st.x / h10 - 1.0).abs() < 1e-9, "{} vs {h10}", st.x);
        assert!((st.va - 10.0).abs() < 1e-9);
    }
}
