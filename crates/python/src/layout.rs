//! The core's layout table (`piezohyst_core::layout`) for Python: slot names of every
//! family row and controller array, so the Python package spells no layout itself.
use piezohyst_core::layout::{ControllerLayout, FamilyLayout, CONTROLLERS, FAMILIES};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::util::bad_arg;

/// Expanded slot names of a family's row for these dims (`p0`, `r[0]`, ...).
pub fn slot_names(layout: &FamilyLayout, dims: &[usize]) -> Vec<String> {
    let mut names = Vec::with_capacity(layout.param_len(dims));
    for (slot, _, len) in layout.ranges(dims) {
        if slot.is_scalar() {
            names.extend((0..len).map(|_| slot.name.to_string()));
        } else {
            names.extend((0..len).map(|k| format!("{}[{k}]", slot.name)));
        }
    }
    names
}

/// The layout of a family with these dims as a dict (see `_core.pyi`).
pub fn family_dict<'py>(py: Python<'py>, name: &str, dims: &[usize]) -> PyResult<Bound<'py, PyDict>> {
    let fam = crate::models::family(name, dims.to_vec())?;
    let layout = fam.layout();
    let d = PyDict::new(py);
    d.set_item("family", layout.name)?;
    d.set_item("code", layout.code)?;
    d.set_item("dim_names", layout.dims.to_vec())?;
    d.set_item("dims", dims.to_vec())?;
    d.set_item("slots", slot_names(layout, dims))?;
    let groups: Vec<(&str, usize, usize)> = layout.ranges(dims).map(|(s, at, len)| (s.name, at, len)).collect();
    d.set_item("groups", groups)?;
    d.set_item("linear", layout.linear.to_vec())?;
    d.set_item("nonnegative", layout.nonnegative.to_vec())?;
    d.set_item("param_len", fam.param_len())?;
    d.set_item("state_len", fam.state_len())?;
    d.set_item("scratch_len", fam.scratch_len())?;
    Ok(d)
}

/// The layout of a controller kind as a dict (see `_core.pyi`).
pub fn controller_dict<'py>(py: Python<'py>, kind: &str) -> PyResult<Bound<'py, PyDict>> {
    let layout = ControllerLayout::by_name(kind).ok_or_else(|| {
        let names: Vec<&str> = CONTROLLERS.iter().map(|c| c.name).collect();
        bad_arg(format!("controller = {kind:?} is unknown; expected one of {}", names.join(", ")))
    })?;
    let d = PyDict::new(py);
    d.set_item("kind", layout.name)?;
    d.set_item("code", layout.code)?;
    d.set_item("slots", layout.slots.to_vec())?;
    d.set_item("param_len", layout.param_len())?;
    Ok(d)
}

/// Slot names and metadata of a family's parameter row: `family`, `code` (the C
/// `PhsFamily`), `dim_names`, `dims`, `slots` (expanded, in row order), `groups` (`(name,
/// offset, length)` per declared slot), `linear` (slot names of the regressor columns),
/// `nonnegative` (the linear slots a fit keeps >= 0), `param_len`, `state_len`, `scratch_len`
/// (derived coefficients a built model borrows: what the C library's `phs_model_sizes` reports).
#[pyfunction]
fn family_layout<'py>(py: Python<'py>, name: &str, dims: Vec<usize>) -> PyResult<Bound<'py, PyDict>> {
    family_dict(py, name, &dims)
}

/// Parameter names and metadata of a controller kind: `kind`, `code` (the C
/// `PhsControllerKind`), `slots`, `param_len`.
#[pyfunction]
fn controller_layout<'py>(py: Python<'py>, kind: &str) -> PyResult<Bound<'py, PyDict>> {
    controller_dict(py, kind)
}

/// `({family: code}, {controller kind: code})` in code order: the C library's codes.
#[pyfunction]
fn layout_codes(py: Python<'_>) -> PyResult<(Bound<'_, PyDict>, Bound<'_, PyDict>)> {
    let f = PyDict::new(py);
    for fam in FAMILIES {
        f.set_item(fam.name, fam.code)?;
    }
    let c = PyDict::new(py);
    for k in CONTROLLERS {
        c.set_item(k.name, k.code)?;
    }
    Ok((f, c))
}

/// Add this module's functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(family_layout, m)?)?;
    m.add_function(wrap_pyfunction!(controller_layout, m)?)?;
    m.add_function(wrap_pyfunction!(layout_codes, m)?)?;
    Ok(())
}
