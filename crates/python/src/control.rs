//! Controller specifications from Python: a kind name with a flat parameter array,
//! optionally behind an inverse hysteresis model and/or with learning (ILC). Specs are
//! owned, validated once while holding the GIL, and built again cheaply inside each
//! (GIL-free) task, where the inverse model borrows its parameter row.
use piezohyst_core::compensated::Compensated;
use piezohyst_core::control::{Controller, Limits};
use piezohyst_core::ilc::Ilc;
use piezohyst_core::layout::{ControllerLayout, Law, CONTROLLERS};
use piezohyst_core::spec::Family;
use piezohyst_core::ModelError;

/// An owned controller description.
#[derive(Debug, Clone)]
pub struct ControllerSpec {
    pub kind: String,
    pub params: Vec<f64>,
    /// Inverse model: family, parameter row, voltage limits.
    pub inverse: Option<(Family, Vec<f64>, [f64; 2])>,
    /// Learning: period, gain, forgetting, lead, delay.
    pub ilc: Option<(usize, f64, f64, usize, usize)>,
}

/// The base law of a kind: the core's one decoder (`piezohyst_core::layout`), with the
/// count and finiteness errors worded for Python callers.
pub fn law(kind: &str, p: &[f64]) -> Result<Law, String> {
    let layout = ControllerLayout::by_name(kind).ok_or_else(|| {
        let names: Vec<&str> = CONTROLLERS.iter().map(|c| c.name).collect();
        format!("controller = {kind:?} is unknown; expected one of {}", names.join(", "))
    })?;
    layout.decode(p).map_err(|e| match e {
        ModelError::Length("params", count, got) => format!("controller {kind:?} takes {count} parameters, got {got}"),
        ModelError::NotFinite("params", k, x) => format!("controller parameters[{k}] = {x} is not finite"),
        e => e.to_string(),
    })
}

/// Build the controller `spec` describes and hand it to `f`. With an inverse model, the
/// learning (if any) acts in the linearized domain, before the inverse.
pub fn with_controller<R>(spec: &ControllerSpec, f: impl FnOnce(&(dyn Controller + Sync)) -> R) -> Result<R, String> {
    let b = law(&spec.kind, &spec.params)?;
    let inner: &(dyn Controller + Sync) = &b;
    type Learning<'c> = Result<Option<Ilc<&'c (dyn Controller + Sync)>>, String>;
    fn learn<'c>(spec: &ControllerSpec, c: &'c (dyn Controller + Sync)) -> Learning<'c> {
        match spec.ilc {
            None => Ok(None),
            Some((n, gain, q, lead, delay)) => {
                Ilc::new(c, n, gain, q, lead, delay).map(Some).map_err(|e| format!("ilc: {e}"))
            }
        }
    }
    match &spec.inverse {
        None => match learn(spec, inner)? {
            None => Ok(f(inner)),
            Some(ilc) => Ok(f(&ilc)),
        },
        Some((family, row, lim)) => {
            let mut scratch = vec![0.0; family.scratch_len()];
            let model = family.build(row, &mut scratch).map_err(|e| format!("inverse model: {e}"))?;
            let limits = Limits::new(lim[0], lim[1]).map_err(|e| format!("inverse: {e}"))?;
            match learn(spec, inner)? {
                None => Ok(f(&Compensated { inner, model, limits })),
                Some(ilc) => Ok(f(&Compensated { inner: ilc, model, limits })),
            }
        }
    }
}
