//! Controller specifications from Python: a kind name with a flat parameter array,
//! optionally behind an inverse hysteresis model and/or with learning (ILC). Specs are
//! owned, validated once while holding the GIL, and built again cheaply inside each
//! (GIL-free) task, where the inverse model borrows its parameter row.
use piezohyst_core::absmc::Absmc;
use piezohyst_core::cemf::{CemfFeedforward, CemfModel};
use piezohyst_core::compensated::Compensated;
use piezohyst_core::control::{Controller, Limits, OpenLoop, Pid, PidConfig, VelocityObserver};
use piezohyst_core::ilc::Ilc;
use piezohyst_core::smc::{Smc, SmcConfig, Switching};
use piezohyst_core::spec::Family;
use piezohyst_core::ModelError;

/// Parameter count per kind (layouts documented in `python/piezohyst/control.py`).
pub const KINDS: [(&str, usize); 5] =
    [("open_loop", 6), ("pid", 9), ("smc", 21), ("absmc", 22), ("cemf_feedforward", 10)];

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

enum Base {
    OpenLoop(OpenLoop),
    Pid(Pid),
    Smc(Smc),
    Absmc(Absmc),
    CemfFeedforward(CemfFeedforward),
}

impl Base {
    fn as_dyn(&self) -> &(dyn Controller + Sync) {
        match self {
            Base::OpenLoop(c) => c,
            Base::Pid(c) => c,
            Base::Smc(c) => c,
            Base::Absmc(c) => c,
            Base::CemfFeedforward(c) => c,
        }
    }
}

fn observer(bandwidth: f64, ts: f64, delay: f64) -> Result<VelocityObserver, ModelError> {
    VelocityObserver::new(bandwidth, ts, delay)
}

fn cemf(p: &[f64]) -> Result<CemfModel, ModelError> {
    CemfModel::from_slice(p)
}

fn base(kind: &str, p: &[f64]) -> Result<Base, String> {
    let count = KINDS.iter().find(|(k, _)| *k == kind).map(|(_, n)| *n).ok_or_else(|| {
        let names: Vec<&str> = KINDS.iter().map(|(k, _)| *k).collect();
        format!("controller = {kind:?} is unknown; expected one of {}", names.join(", "))
    })?;
    if p.len() != count {
        return Err(format!("controller {kind:?} takes {count} parameters, got {}", p.len()));
    }
    if let Some(k) = p.iter().position(|x| !x.is_finite()) {
        return Err(format!("controller parameters[{k}] = {} is not finite", p[k]));
    }
    let built = || -> Result<Base, ModelError> {
        let n = p.len();
        let limits = Limits::new(p[n - 2], p[n - 1])?;
        Ok(match kind {
            "open_loop" => Base::OpenLoop(OpenLoop::new(p[0], p[1], p[2], p[3], limits)?),
            "pid" => Base::Pid(Pid::new(PidConfig {
                kp: p[0],
                ki: p[1],
                kd: p[2],
                tau_d: p[3],
                ts: p[4],
                ff_gain: p[5],
                offset: p[6],
                limits,
            })?),
            "smc" => {
                let switching = match p[6] {
                    x if x == 0.0 => Switching::BoundaryLayer { gain: p[7], width: p[8] },
                    x if x == 1.0 => Switching::SuperTwisting { k1: p[7], k2: p[8] },
                    x => {
                        return Err(ModelError::NotFinite(
                            "switching (0 boundary layer, 1 super-twisting)",
                            usize::MAX,
                            x,
                        ))
                    }
                };
                let model = if p[12] != 0.0 {
                    Some(cemf(&[p[0], p[1], p[2], p[13], p[14], p[15], p[16], p[17]])?)
                } else {
                    None
                };
                let smc = Smc::new(SmcConfig {
                    m: p[0],
                    b: p[1],
                    k: p[2],
                    kp: p[3],
                    kv: p[4],
                    alpha: p[5],
                    switching,
                    cemf: model,
                    desired_model_terms: p[18] != 0.0,
                    observer: observer(p[9], p[10], p[11])?,
                    limits,
                })?;
                Base::Smc(smc)
            }
            "absmc" => Base::Absmc(
                Absmc {
                    b: p[0],
                    theta0: [p[1], p[2]],
                    theta_min: [p[3], p[4]],
                    theta_max: [p[5], p[6]],
                    c1: p[7],
                    lambda: p[8],
                    ks: p[9],
                    phi: p[10],
                    gamma_theta: [p[11], p[12]],
                    gamma_d: p[13],
                    d0: p[14],
                    d_max: p[15],
                    desired_regressor: p[16] != 0.0,
                    observer: observer(p[17], p[18], p[19])?,
                    limits,
                }
                .validated()?,
            ),
            "cemf_feedforward" => Base::CemfFeedforward(CemfFeedforward { model: cemf(&p[..8])?, limits }),
            _ => unreachable!("kind checked above"),
        })
    };
    built().map_err(|e| e.to_string())
}

/// Build the controller `spec` describes and hand it to `f`. With an inverse model, the
/// learning (if any) acts in the linearized domain, before the inverse.
pub fn with_controller<R>(spec: &ControllerSpec, f: impl FnOnce(&(dyn Controller + Sync)) -> R) -> Result<R, String> {
    let b = base(&spec.kind, &spec.params)?;
    let inner = b.as_dyn();
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
