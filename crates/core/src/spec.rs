//! Flat parameter rows: every model family as one `f64` row, so that Python, the batch
//! engine and the C ABI describe a parameter set the same way. The row layouts (slot names
//! and order) are declared once, in [`crate::layout::FAMILIES`]; this module builds a model
//! from a row. Envelope kinds: 0 identity, 1 polynomial, 2 tanh (coefficients are ignored
//! for identity).
use crate::creep::{lag_gains, Creep};
use crate::differential::{BoucWen, Dahl, Duhem};
use crate::envelope::Envelope;
use crate::error::ModelError;
use crate::generalized::GeneralizedPi;
use crate::layout::FamilyLayout;
use crate::pi::Pi;
use crate::preisach::{cell_count, row_prefix, Preisach};
use crate::rate::RateDependentPi;
use crate::{Hysteresis, Invertible};

/// A model family with its structural sizes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Classical PI.
    Pi { n: usize, creep: usize },
    /// Generalized PI / MPI.
    Gpi { n: usize, rising: usize, falling: usize, creep: usize },
    /// Rate-dependent PI.
    Rdpi { n: usize, creep: usize },
    /// Creep alone.
    Creep { terms: usize },
    /// Discretized Preisach (with an optional creep bank, as the PI family).
    Preisach { levels: usize, memory: usize, creep: usize },
    /// Bouc–Wen.
    BoucWen,
    /// Generalized Duhem.
    Duhem,
    /// Dahl.
    Dahl,
}

/// Operators per model are capped so a typo cannot ask for terabytes.
pub const MAX_OPERATORS: usize = 100_000;

impl Family {
    /// Parse a family name and its dims (the rows of [`crate::layout::FAMILIES`]).
    pub fn parse(name: &str, dims: &[usize]) -> Result<Self, ModelError> {
        FamilyLayout::by_name(name).ok_or(ModelError::Structure("family (unknown name)", 0))?.family(dims)
    }

    /// The family's row of the layout table.
    pub fn layout(&self) -> &'static FamilyLayout {
        let name = match self {
            Family::Pi { .. } => "pi",
            Family::Gpi { .. } => "gpi",
            Family::Rdpi { .. } => "rdpi",
            Family::Creep { .. } => "creep",
            Family::Preisach { .. } => "preisach",
            Family::BoucWen => "boucwen",
            Family::Duhem => "duhem",
            Family::Dahl => "dahl",
        };
        FamilyLayout::by_name(name).expect("every family has a layout row")
    }

    /// The dims this family was parsed from (`.0[..len]`, `len = .1`).
    pub fn dims(&self) -> ([usize; 4], usize) {
        match *self {
            Family::Pi { n, creep } | Family::Rdpi { n, creep } => ([n, creep, 0, 0], 2),
            Family::Gpi { n, rising, falling, creep } => ([n, rising, falling, creep], 4),
            Family::Creep { terms } => ([terms, 0, 0, 0], 1),
            Family::Preisach { levels, memory, creep } => ([levels, memory, creep, 0], 3),
            Family::BoucWen | Family::Duhem | Family::Dahl => ([0; 4], 0),
        }
    }

    fn creep_terms(&self) -> usize {
        match *self {
            Family::Pi { creep, .. }
            | Family::Gpi { creep, .. }
            | Family::Rdpi { creep, .. }
            | Family::Preisach { creep, .. } => creep,
            Family::Creep { terms } => terms,
            _ => 0,
        }
    }

    fn creep_tail_len(&self) -> usize {
        let m = self.creep_terms();
        match self {
            Family::Creep { .. } => 1 + 2 * m,
            _ if m > 0 => 1 + 2 * m,
            _ => 0,
        }
    }

    /// Length of a parameter row (summed over the family's slots in the layout table).
    pub fn param_len(&self) -> usize {
        let (dims, n) = self.dims();
        self.layout().param_len(&dims[..n])
    }

    /// Length of a state vector.
    pub fn state_len(&self) -> usize {
        let base = match *self {
            Family::Pi { n, .. } | Family::Gpi { n, .. } => n,
            Family::Rdpi { n, .. } => n + 3,
            Family::Creep { .. } => 0,
            Family::Preisach { memory, .. } => 2 + memory,
            Family::BoucWen | Family::Duhem | Family::Dahl => 2,
        };
        base + self.creep_terms()
    }

    /// Scratch the built model borrows (derived coefficients).
    pub fn scratch_len(&self) -> usize {
        let pre = match *self {
            Family::Preisach { levels, .. } => cell_count(levels),
            _ => 0,
        };
        pre + self.creep_terms()
    }

    /// Build the model of one row; `scratch` must have [`Family::scratch_len`] slots and
    /// lives as long as the model.
    pub fn build<'a>(&self, row: &'a [f64], scratch: &'a mut [f64]) -> Result<Model<'a>, ModelError> {
        if row.len() != self.param_len() {
            return Err(ModelError::Length("params", self.param_len(), row.len()));
        }
        if scratch.len() != self.scratch_len() {
            return Err(ModelError::Length("scratch", self.scratch_len(), scratch.len()));
        }
        let m = self.creep_terms();
        let split = row.len() - self.creep_tail_len();
        let (head, tail) = row.split_at(split);
        let (pre_scratch, creep_scratch) = scratch.split_at_mut(scratch.len() - m);
        let creep = if self.creep_tail_len() > 0 {
            let ts = tail[0];
            lag_gains(ts, &tail[1..1 + m], creep_scratch)?;
            let gains: &'a [f64] = creep_scratch;
            Some(Creep::new(gains, &tail[1 + m..])?)
        } else {
            None
        };
        let base = match *self {
            Family::Pi { n, .. } => Base::Pi(Pi::new(head[0], &head[1..1 + n], &head[1 + n..])?),
            Family::Gpi { n, rising, falling, .. } => {
                let c4 = |o: usize| [head[o], head[o + 1], head[o + 2], head[o + 3]];
                Base::Gpi(GeneralizedPi::new(
                    c4(2),
                    &head[14..14 + n],
                    &head[14 + n..],
                    Envelope::from_code(rising, c4(6))?,
                    Envelope::from_code(falling, c4(10))?,
                    (head[0], head[1]),
                )?)
            }
            Family::Rdpi { n, .. } => Base::Rdpi(RateDependentPi::new(
                head[0],
                head[1],
                head[2],
                head[3],
                &head[4..4 + n],
                &head[4 + n..4 + 2 * n],
                &head[4 + 2 * n..],
            )?),
            Family::Creep { .. } => Base::Nothing,
            Family::Preisach { levels, memory, .. } => {
                let w = &head[4..];
                crate::error::check_finite("weights", w)?;
                row_prefix(levels, w, pre_scratch);
                let prefix: &'a [f64] = pre_scratch;
                Base::Preisach(
                    Preisach {
                        lo: head[0],
                        hi: head[1],
                        levels,
                        weights: w,
                        prefix,
                        offset: head[2],
                        slope: head[3],
                        memory,
                    }
                    .validated()?,
                )
            }
            Family::BoucWen => Base::BoucWen(BoucWen::new(head[0], head[1], head[2], head[3], head[4])?),
            Family::Duhem => Base::Duhem(Duhem::new(
                head[0],
                [head[1], head[2], head[3], head[4]],
                [head[5], head[6], head[7], head[8]],
            )?),
            Family::Dahl => Base::Dahl(Dahl::new(head[0], head[1], head[2])?),
        };
        Ok(Model { base, creep })
    }
}

/// The rate-independent or rate-dependent part of a built model.
#[derive(Debug, Clone, Copy)]
pub enum Base<'a> {
    /// No base part (creep alone).
    Nothing,
    /// Classical PI.
    Pi(Pi<'a>),
    /// GPI / MPI.
    Gpi(GeneralizedPi<'a>),
    /// Rate-dependent PI.
    Rdpi(RateDependentPi<'a>),
    /// Preisach.
    Preisach(Preisach<'a>),
    /// Bouc–Wen.
    BoucWen(BoucWen),
    /// Duhem.
    Duhem(Duhem),
    /// Dahl.
    Dahl(Dahl),
}

/// A model built from a row: base part plus optional creep (`y = base + creep`).
#[derive(Debug, Clone, Copy)]
pub struct Model<'a> {
    /// Base part.
    pub base: Base<'a>,
    /// Creep part.
    pub creep: Option<Creep<'a>>,
}

macro_rules! on_base {
    ($b:expr, $m:ident => $e:expr, $none:expr) => {
        match $b {
            Base::Nothing => $none,
            Base::Pi($m) => $e,
            Base::Gpi($m) => $e,
            Base::Rdpi($m) => $e,
            Base::Preisach($m) => $e,
            Base::BoucWen($m) => $e,
            Base::Duhem($m) => $e,
            Base::Dahl($m) => $e,
        }
    };
}

impl Model<'_> {
    fn base_len(&self) -> usize {
        on_base!(&self.base, m => m.state_len(), 0)
    }
}

impl Hysteresis for Model<'_> {
    fn state_len(&self) -> usize {
        self.base_len() + self.creep.as_ref().map_or(0, |c| c.state_len())
    }
    fn reset(&self, state: &mut [f64]) {
        let (a, b) = state.split_at_mut(self.base_len());
        on_base!(&self.base, m => m.reset(a), ());
        if let Some(c) = &self.creep {
            c.reset(b);
        }
    }
    fn check_state(&self, state: &[f64]) -> Result<(), ModelError> {
        crate::hysteresis::check_state_len(state, self.state_len())?;
        on_base!(&self.base, m => m.check_state(&state[..self.base_len()]), Ok(()))?;
        // the creep slots follow the base's: indices name slots of the whole state
        crate::error::check_finite("state", state)
    }
    #[inline]
    fn step(&self, state: &mut [f64], v: f64) -> f64 {
        let (a, b) = state.split_at_mut(self.base_len());
        let y = on_base!(&self.base, m => m.step(a, v), 0.0);
        match &self.creep {
            Some(c) => y + c.step(b, v),
            None => y,
        }
    }
}

/// Trial by stepping a copy of a small state (models without an analytic slope).
fn trial_by_copy<M: Hysteresis>(m: &M, state: &[f64], v: f64) -> (f64, f64) {
    let mut buf = [0.0; 2];
    buf.copy_from_slice(&state[..2]);
    (m.step(&mut buf, v), f64::NAN)
}

impl Invertible for Model<'_> {
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64) {
        let (a, b) = state.split_at(self.base_len());
        let (y, d) = match &self.base {
            Base::Nothing => (0.0, 0.0),
            Base::Pi(m) => m.trial(a, v),
            Base::Gpi(m) => m.trial(a, v),
            Base::Rdpi(m) => m.trial(a, v),
            Base::Preisach(m) => m.trial(a, v),
            Base::BoucWen(m) => m.trial(a, v),
            Base::Duhem(m) => trial_by_copy(m, a, v),
            Base::Dahl(m) => trial_by_copy(m, a, v),
        };
        match &self.creep {
            Some(c) => {
                let (y2, d2) = c.trial(b, v);
                (y + y2, d + d2)
            }
            None => (y, d),
        }
    }
}

impl Family {
    /// Number of regressor columns of [`Model::regressors_step`] (see there).
    pub fn regressor_count(&self) -> usize {
        let base = match *self {
            Family::Pi { n, .. } => 1 + n,
            Family::Gpi { n, .. } => 4 + n,
            Family::Rdpi { n, .. } => 1 + 2 * n,
            Family::Creep { .. } => 0,
            Family::Preisach { levels, .. } => 2 + cell_count(levels),
            Family::BoucWen | Family::Duhem | Family::Dahl => 0,
        };
        base + self.creep_terms()
    }
}

impl Model<'_> {
    /// Advance one sample and write the regressors: the quantities the output is linear in
    /// once the structure (thresholds, envelopes, rate terms, creep time constants) is fixed.
    /// Columns: PI `[v, z_1..z_n]`; GPI/MPI `[1, v, v^2, v^3, z_1..z_n]`; RDPI
    /// `[v, z_1..z_n, rate z_1..rate z_n]`; Preisach `[1, v, cell fractions...]`; then the
    /// creep lag outputs `[w_1..w_m]`. The output equals the row's linear parameters dotted
    /// with them. Returns `false` for models that are not linear in any parameters.
    pub fn regressors_step(&self, state: &mut [f64], v: f64, out: &mut [f64]) -> bool {
        let (a, b) = state.split_at_mut(self.base_len());
        let used = match &self.base {
            Base::Pi(m) => {
                m.step(a, v);
                out[0] = v;
                out[1..1 + a.len()].copy_from_slice(a);
                1 + a.len()
            }
            Base::Gpi(m) => {
                m.step(a, v);
                out[..4].copy_from_slice(&[1.0, v, v * v, v * v * v]);
                out[4..4 + a.len()].copy_from_slice(a);
                4 + a.len()
            }
            Base::Rdpi(m) => {
                m.step(a, v);
                let n = m.thresholds.len();
                let rate = a[n + 1];
                out[0] = v;
                for i in 0..n {
                    out[1 + i] = a[i];
                    out[1 + n + i] = rate * a[i];
                }
                1 + 2 * n
            }
            Base::Preisach(m) => {
                m.step(a, v);
                out[0] = 1.0;
                out[1] = v;
                m.cell_fractions(a, &mut out[2..2 + cell_count(m.levels)]);
                2 + cell_count(m.levels)
            }
            Base::Nothing => 0,
            _ => return false,
        };
        if let Some(c) = &self.creep {
            c.step(b, v);
            out[used..used + b.len()].copy_from_slice(b);
        }
        true
    }
}
