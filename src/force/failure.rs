//! Interfaces that fail: the plastic part of the internal forces of the interfaces whose law
//! (eq. 11, [`InterfaceLaw`]) is not linear, such as a strength ([`crate::model::law::Strength`]).
//!
//! The traction at a Gauss point is `λ = diag(k_n, k_s) (δ − δ_p)`, so the internal forces
//! split into the elastic ones of the evaluator and a plastic correction:
//! `f_int = f_el(U) − f_p`, `f_p = Σ_gp t w Bᵀ diag(k_n, k_s) δ_p` (eq. 7 with the plastic
//! relative displacements as eigen-displacements). The evaluators keep their elastic hot loops
//! untouched; the correction is computed in their own manner: the assembled evaluator stores
//! `G = Σ t w Bᵀ diag(k)` as blocks per element and multiplies `f_p = G δ_p`; the element-wise
//! one forms each element's share from its own edges' Gauss points, `±N_e(x)ᵀ T_p`, with no
//! stored matrix (eq. 15). Both update the state the same way, [`PlasticForces::update`]: the
//! relative displacement `δ = N_b U_b − N_a U_a` at each Gauss point and the return mapping of
//! its law ([`InterfaceLaw::update`]), once per evaluation, that is once per time step.
//!
//! Only the interfaces between elements whose law is not linear have points; ground springs
//! (supports) keep their law's springs.
//!
//! **Hand-over to contact.** In a scene with edge-to-edge contact a broken interface whose
//! elements have moved apart by more than [`RELEASE`] of its length (in opening or in slip),
//! beyond the range where its linear kinematics hold, is *released*: its springs stop acting
//! (`δ_p` follows `δ`, the traction is zero) and its two elements touch through edge-to-edge
//! contact from then on, so that the fragments the released interfaces cut out collide as
//! blocks (`force::contact`, where every element of a body that fragments is a contact body). The elastic energy the interface still held goes to the contact account
//! ([`FailureState::handover`]); both sides' forces stay equal and opposite, so momentum is
//! kept.

use crate::input::names::named;
use crate::input::scene::EvaluatorKind;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Formulation, Hybrid, Kinematics, Rigid};
use crate::model::law::{InterfaceLaw, LawPoint};
use crate::model::Model;
use crate::parallel::for_each_chunk;
use rayon::prelude::*;
use std::marker::PhantomData;
use std::sync::Arc;

/// A broken interface is released to contact once its elements have moved apart by more than
/// this fraction of its length.
pub const RELEASE: f64 = 0.01;

/// The state of every Gauss point of the failing interfaces: two per interface, in the order of
/// [`PlasticForces::interfaces`].
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FailureState {
    /// One per Gauss point.
    pub points: Vec<LawPoint>,
    /// Per failing interface, whether it has been released to contact (only in scenes whose
    /// fragments collide, else all false).
    pub released: Vec<bool>,
    /// The elastic energy the released interfaces held when they were released (J): contact
    /// energy from then on.
    pub handover: f64,
    /// Whether the last update released an interface (contact must be told).
    pub changed: bool,
    /// Whether any point has a plastic displacement after the last update: until one has, the
    /// plastic forces and the energy offset are zero and are not computed. Set by every update,
    /// so not saved.
    #[serde(skip)]
    pub plastic: bool,
}

impl FailureState {
    /// Becomes a copy of `other` in the room it has (the derived `clone_from` would allocate).
    pub fn copy_from(&mut self, other: &FailureState) {
        self.points.clone_from(&other.points);
        self.released.clone_from(&other.released);
        self.handover = other.handover;
        self.changed = other.changed;
        self.plastic = other.plastic;
    }
}

named! {
    /// The state of a failing interface, from its two Gauss points; serialised (in
    /// `final_state.json`) as its name. `ALL` is in the order of the crack-frame codes
    /// (`output::vtk::status_code`).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum InterfaceStatus {
        /// No plastic displacement.
        "elastic" => Elastic,
        /// Plastic displacement, strength left.
        "yielding" => Yielding,
        /// Strength exhausted at both Gauss points.
        "broken" => Broken,
        /// Broken and handed over to contact.
        "released" => Released,
    }
}

/// What an interface has done so far, from its two Gauss points.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct InterfaceFailure {
    /// The interface (index in `Model::interfaces`).
    pub interface: usize,
    /// Its state.
    pub status: InterfaceStatus,
    /// Mean plastic opening `δ_p,n` (m): the crack opening.
    pub opening: f64,
    /// Mean plastic slip `δ_p,s` (m).
    pub slip: f64,
    /// Work of the strength and of friction on the interface (J).
    pub dissipated: f64,
}

/// The plastic correction of the internal forces and the state update, for one model and one
/// evaluator kind.
pub trait PlasticForces: Send + Sync {
    /// The failing interfaces (indices in `Model::interfaces`), two Gauss points each.
    fn interfaces(&self) -> &[u32];
    /// A state with every point elastic.
    fn initial(&self) -> FailureState {
        FailureState {
            points: vec![LawPoint::default(); 2 * self.interfaces().len()],
            released: vec![false; self.interfaces().len()],
            handover: 0.0,
            changed: false,
            plastic: false,
        }
    }
    /// The return mapping at every Gauss point for the displacements `u`.
    fn update(&self, u: &[f64], state: &mut FailureState);
    /// `f −= f_p`: with `f = f_el(U)`, the internal forces `f_int = f_el − f_p`.
    fn subtract_plastic(&self, state: &FailureState, f: &mut [f64]);
    /// `½ Uᵀ f_int` minus the elastic energy `½ Σ t w (δ − δ_p)ᵀ k (δ − δ_p)` of the failing
    /// interfaces: `½ Σ t w (δ − δ_p)ᵀ k δ_p` (J).
    fn energy_offset(&self, u: &[f64], state: &FailureState) -> f64;
    /// The work of the strengths and of friction so far (J).
    fn dissipated(&self, state: &FailureState) -> [f64; 2];
    /// Each failing interface's status, openings and dissipated work.
    fn report(&self, state: &FailureState) -> Vec<InterfaceFailure>;
}

/// The plastic forces of `model` for the evaluator `kind`; `None` when no interface can fail.
pub fn build(model: &Model, kind: EvaluatorKind) -> Option<Box<dyn PlasticForces>> {
    if !model.any_fails() {
        return None;
    }
    Some(match model.formulation {
        Formulation::Rigid => Box::new(Points::<Rigid, 3>::new(model, kind)),
        Formulation::Hybrid { .. } => Box::new(Points::<Hybrid, 6>::new(model, kind)),
    })
}

/// One Gauss point of a failing interface.
#[derive(Debug, Clone, Copy)]
struct Point {
    a: u32,
    /// The other element (supports have no points: `Model::fails`).
    b: u32,
    /// The point from the centroids of `a` and `b` (m).
    da: Vec2,
    db: Vec2,
    normal: Vec2,
    tangent: Vec2,
    /// Elastic springs `(k_n, k_s)` (Pa/m).
    k: [f64; 2],
    /// `t w`: thickness times the Gauss weight `L/2` (m²).
    tw: f64,
    /// Its law, in `Points::laws` (an index: the points stay small).
    law: u32,
}

impl Point {
    /// `δ = N_b U_b − N_a U_a` on the interface's axes, `(δ_n, δ_s)`.
    #[inline]
    fn delta<K: Kinematics<N>, const N: usize>(&self, u: &[[f64; N]]) -> [f64; 2] {
        let mut d = -K::displacement(&u[self.a as usize], self.da);
        d += K::displacement(&u[self.b as usize], self.db);
        [self.normal.dot(&d), self.tangent.dot(&d)]
    }

    /// `T_p = t w (k_n δ_p,n n + k_s δ_p,s s)`: the traction that `δ_p` relieves, as a force.
    #[inline]
    fn plastic_force(&self, p: &[f64; 2]) -> Vec2 {
        self.tw * (self.k[0] * p[0] * self.normal + self.k[1] * p[1] * self.tangent)
    }
}

/// How an evaluator forms `f_p`: per element, its Gauss points with a sign and an offset
/// (element-wise), or the blocks `G_ej` of `f_p = G δ_p` (assembled).
enum Correction<const N: usize> {
    ElementWise(Vec<(u32, f64, Vec2)>),
    Assembled(Vec<(u32, [[f64; 2]; N])>),
}

struct Points<K: Kinematics<N>, const N: usize> {
    points: Vec<Point>,
    /// The model's laws ([`Model::laws`]), then its default law.
    laws: Vec<Arc<dyn InterfaceLaw>>,
    interfaces: Vec<u32>,
    /// Per failing interface, the separation beyond which a broken one is released (m):
    /// [`RELEASE`] of its length where its body fragments (`Model::fragments`), else infinite;
    /// empty when no body fragments (then no step looks for releases).
    release: Vec<f64>,
    /// Entries of element `e` are `row_start[e] .. row_start[e + 1]` of `correction`.
    row_start: Vec<u32>,
    correction: Correction<N>,
    kinematics: PhantomData<K>,
}

impl<K: Kinematics<N>, const N: usize> Points<K, N> {
    fn new(model: &Model, kind: EvaluatorKind) -> Self {
        let mut points = Vec::new();
        let mut laws = model.laws.clone();
        laws.push(model.law.clone());
        let mut interfaces = Vec::new();
        let mut release = Vec::new();
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        let fragments: Vec<bool> = (0..model.bodies.len())
            .map(|b| model.fragments(b))
            .collect();
        for (k, i) in model.interfaces.iter().enumerate() {
            if !model.fails(i) {
                continue;
            }
            // The model's laws, then its default law (`laws`).
            let law = match i.law {
                crate::model::DEFAULT_LAW => model.laws.len() as u32,
                k => k,
            };
            interfaces.push(k as u32);
            let body = model.elements[i.a as usize].body as usize;
            release.push(if fragments[body] {
                RELEASE * i.length
            } else {
                f64::INFINITY
            });
            let (gauss, w) = i.gauss_points();
            for x in gauss {
                points.push(Point {
                    a: i.a,
                    b: i.b,
                    da: x - centroid(i.a),
                    db: x - centroid(i.b),
                    normal: i.normal,
                    tangent: i.tangent,
                    k: laws[law as usize].springs([i.k_n, i.k_s]),
                    tw: model.thickness * w,
                    law,
                });
            }
        }
        // Each element's entries: its points as side `a` (f_int gains `N_aᵀ T_p`) and as side
        // `b` (loses `N_bᵀ T_p`), in point order.
        let mut entries: Vec<(u32, u32, f64, Vec2)> = Vec::with_capacity(2 * points.len());
        for (j, p) in points.iter().enumerate() {
            entries.push((p.a, j as u32, 1.0, p.da));
            entries.push((p.b, j as u32, -1.0, p.db));
        }
        entries.sort_by_key(|&(e, j, _, _)| (e, j));
        let mut row_start = vec![0u32; model.elements.len() + 1];
        for &(e, ..) in &entries {
            row_start[e as usize + 1] += 1;
        }
        for e in 0..model.elements.len() {
            row_start[e + 1] += row_start[e];
        }
        let correction = match kind {
            EvaluatorKind::ElementWise => {
                Correction::ElementWise(entries.iter().map(|&(_, j, s, d)| (j, s, d)).collect())
            }
            EvaluatorKind::Assembled => Correction::Assembled(
                entries
                    .iter()
                    .map(|&(_, j, sign, d)| {
                        let p = &points[j as usize];
                        // Column c of the block: N(d)ᵀ of the unit plastic force of δ_p,c.
                        let mut cols = [[0.0; N]; 2];
                        K::add_force(&mut cols[0], d, sign * p.tw * p.k[0] * p.normal);
                        K::add_force(&mut cols[1], d, sign * p.tw * p.k[1] * p.tangent);
                        (j, std::array::from_fn(|r| [cols[0][r], cols[1][r]]))
                    })
                    .collect(),
            ),
        };
        if release.iter().all(|r| r.is_infinite()) {
            release.clear();
        }
        Points {
            points,
            laws,
            interfaces,
            release,
            row_start,
            correction,
            kinematics: PhantomData,
        }
    }
}

impl<K: Kinematics<N>, const N: usize> PlasticForces for Points<K, N> {
    fn interfaces(&self) -> &[u32] {
        &self.interfaces
    }

    fn update(&self, u: &[f64], state: &mut FailureState) {
        let (u, _) = u.as_chunks::<N>();
        let released = &state.released;
        // Whether any point is plastic after its update: summed without short cut, so that
        // every point is updated.
        state.plastic = state
            .points
            .par_iter_mut()
            .zip(self.points.par_iter())
            .enumerate()
            .with_min_len(4096)
            .map(|(j, (s, p))| {
                let delta = p.delta::<K, N>(u);
                if released[j / 2] {
                    s.p = delta;
                } else {
                    self.laws[p.law as usize].update(p.k, delta, s);
                }
                s.p != [0.0; 2]
            })
            .reduce(|| false, |a, b| a | b);
        // Hand-over: broken interfaces whose elements moved apart beyond their range.
        state.changed = false;
        for (k, &range) in self.release.iter().enumerate() {
            if range.is_infinite() || state.released[k] {
                continue;
            }
            let (p, s) = (
                &self.points[2 * k..2 * k + 2],
                &mut state.points[2 * k..2 * k + 2],
            );
            if !(0..2).all(|g| self.laws[p[g].law as usize].is_broken(&s[g])) {
                continue;
            }
            let d = [0, 1].map(|g| p[g].delta::<K, N>(u));
            if (0..2).any(|c| (0.5 * (d[0][c] + d[1][c])).abs() > range) {
                for g in 0..2 {
                    let e = [d[g][0] - s[g].p[0], d[g][1] - s[g].p[1]];
                    state.handover +=
                        0.5 * p[g].tw * (p[g].k[0] * e[0] * e[0] + p[g].k[1] * e[1] * e[1]);
                    s[g].p = d[g];
                }
                state.released[k] = true;
                state.changed = true;
                state.plastic = true;
            }
        }
    }

    fn subtract_plastic(&self, state: &FailureState, f: &mut [f64]) {
        if !state.plastic {
            return;
        }
        let (f, _) = f.as_chunks_mut::<N>();
        let state = &state.points;
        for_each_chunk(f, |first, rows| {
            for (i, fe) in rows.iter_mut().enumerate() {
                let e = first + i;
                let range = self.row_start[e] as usize..self.row_start[e + 1] as usize;
                match &self.correction {
                    Correction::ElementWise(entries) => {
                        for &(j, sign, d) in &entries[range] {
                            let j = j as usize;
                            let t = self.points[j].plastic_force(&state[j].p);
                            K::add_force(fe, d, sign * t);
                        }
                    }
                    Correction::Assembled(blocks) => {
                        for (j, g) in &blocks[range] {
                            let p = &state[*j as usize].p;
                            for r in 0..N {
                                fe[r] += g[r][0] * p[0] + g[r][1] * p[1];
                            }
                        }
                    }
                }
            }
        });
    }

    fn energy_offset(&self, u: &[f64], state: &FailureState) -> f64 {
        if !state.plastic {
            return 0.0;
        }
        let (u, _) = u.as_chunks::<N>();
        self.points
            .iter()
            .zip(&state.points)
            .map(|(p, s)| {
                let d = p.delta::<K, N>(u);
                0.5 * p.tw
                    * (0..2)
                        .map(|c| (d[c] - s.p[c]) * p.k[c] * s.p[c])
                        .sum::<f64>()
            })
            .sum()
    }

    fn dissipated(&self, state: &FailureState) -> [f64; 2] {
        self.points
            .iter()
            .zip(&state.points)
            .fold([0.0; 2], |[a, b], (p, s)| {
                [a + p.tw * s.fracture, b + p.tw * s.friction]
            })
    }

    fn report(&self, state: &FailureState) -> Vec<InterfaceFailure> {
        self.interfaces
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let (p, s) = (
                    &self.points[2 * k..2 * k + 2],
                    &state.points[2 * k..2 * k + 2],
                );
                let broken = (0..2).all(|g| self.laws[p[g].law as usize].is_broken(&s[g]));
                let plastic = s.iter().any(|s| s.p != [0.0; 2]);
                InterfaceFailure {
                    interface: i as usize,
                    status: if state.released[k] {
                        InterfaceStatus::Released
                    } else if broken {
                        InterfaceStatus::Broken
                    } else if plastic {
                        InterfaceStatus::Yielding
                    } else {
                        InterfaceStatus::Elastic
                    },
                    opening: 0.5 * (s[0].p[0] + s[1].p[0]),
                    slip: 0.5 * (s[0].p[1] + s[1].p[1]),
                    dissipated: (0..2)
                        .map(|g| p[g].tw * (s[g].fracture + s[g].friction))
                        .sum(),
                }
            })
            .collect()
    }
}
