//! Warnings about inputs at the method's extremes (validation §10): the run goes on, but the
//! user is told what the measured behaviour there is.

use crate::model::formulation::Formulation;
use crate::model::Model;

/// Element aspect ratio (`√(I_max/I_min)` of the area moments: `a/b` for an `a × b` rectangle)
/// above which a warning is given.
pub const ASPECT_LIMIT: f64 = 100.0;
/// Ratio of the largest to the smallest element size (`√A`) above which a warning is given.
pub const SIZE_LIMIT: f64 = 100.0;
/// Hybrid penalty above which a warning is given.
pub const PENALTY_LIMIT: f64 = 1e6;

/// The aspect ratio of an element from its central second moments.
pub fn aspect_ratio(p: &crate::mesh::geometry::AreaProperties) -> f64 {
    let (a, b, c) = (p.i_xx, p.i_yy, p.i_xy);
    let mean = 0.5 * (a + b);
    let r = (0.25 * (a - b) * (a - b) + c * c).sqrt();
    ((mean + r) / (mean - r).max(f64::MIN_POSITIVE)).sqrt()
}

/// The warnings for extreme inputs of a model (the time step's is
/// `analysis::limit::Limit::warning`).
pub fn warnings(model: &Model) -> Vec<String> {
    let mut out = Vec::new();
    if let Formulation::Hybrid { penalty } = model.formulation {
        if penalty > PENALTY_LIMIT {
            out.push(format!(
                "penalty p = {penalty:e}: Δt_crit shrinks as 1/√p and static solutions lose about log10(p) digits to round-off \
                 (validation §10.1); p ≤ 1e4 already makes the interfaces stiff to 1/p"
            ));
        }
    }
    let (worst, e) = model
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| (aspect_ratio(&el.props), e))
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
    if worst > ASPECT_LIMIT {
        out.push(format!(
            "element {e} has an aspect ratio of {worst:.0}: its rotation is stiff and Δt_crit is \
                set by its short side (validation §10.2)"
        ));
    }
    let sizes = model.elements.iter().map(|el| el.props.area.sqrt());
    let (lo, hi) = sizes.fold((f64::INFINITY, 0.0f64), |a, s| (a.0.min(s), a.1.max(s)));
    if hi / lo > SIZE_LIMIT {
        out.push(format!(
            "element sizes span 1:{:.0}: Δt_crit is set by the smallest elements, and the largest step at a small fraction of \
             their own limit (validation §10.3)",
            hi / lo
        ));
    }
    for body in &model.bodies {
        let [e_n, e_s] = body.moduli;
        // E_s/E_n = 1 − ν (plane stress; ν' in plane strain).
        let nu = 1.0 - e_s / e_n;
        // Only hybrid elements have an interior that `ν` stiffens: rigid cells take it as the
        // ratio of their springs (a calibration's knob).
        if nu > 0.45 && matches!(model.formulation, Formulation::Hybrid { .. }) {
            out.push(format!(
                "body `{}`: ν = {nu:.3} (in the springs' plane) is nearly incompressible: the hybrid interior stiffness grows as \
                 1/(1 − 2ν) in plane strain (validation §10.4)",
                body.name
            ));
        } else if nu < -0.5 {
            out.push(format!(
                "body `{}`: ν = {nu:.3} (in the springs' plane): the shear springs are {:.2} × the normal ones; the rigid \
                 formulation does not represent a negative Poisson ratio (validation §10.4)",
                body.name,
                e_s / e_n
            ));
        }
    }
    out
}

/// Rotation (rad) above which the small-rotation kinematics of the interface springs (eq. 10)
/// is warned about for a meshed body.
pub const ROTATION_LIMIT: f64 = 0.1;

/// The largest `|θ|` of the elements in state `u`; only over bodies of more than one element
/// when `meshed_only` (a one-element body has no interface springs, and its contact geometry
/// uses the finite rotation).
pub fn largest_rotation(model: &Model, u: &[f64], meshed_only: bool) -> f64 {
    let nd = model.formulation.ndof();
    model
        .bodies
        .iter()
        .filter(|b| !meshed_only || b.mesh.n_cells() > 1)
        .flat_map(|b| b.first_element..b.first_element + b.mesh.n_cells())
        .map(|e| u[e * nd + 2].abs())
        .fold(0.0, f64::max)
}

/// The warning for a meshed body that turned by `rotation` (rad), if it is large.
pub fn rotation_warning(rotation: f64) -> Option<String> {
    (rotation > ROTATION_LIMIT).then(|| {
        format!(
            "a meshed body turned by {rotation:.2} rad: the interface springs use small rotations (eq. 10), so a large rigid \
             rotation strains them spuriously (validation §10.6)"
        )
    })
}
