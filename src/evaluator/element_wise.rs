//! The element-wise evaluator (eqs. 15–16): each element's force is the resultant of the
//! tractions `λ = diag(k_n, k_s) δ` on its own edges, integrated by the edge's 2-point Gauss rule.
//! No global matrix.
//!
//! The two Gauss points of an edge sit at `m ± g` about its midpoint `m`, with
//! `g = L/(2√3) s` along the edge. The displacement jump is affine along the edge,
//! `δ(m ± g) = δ₀ ± δ₁`, so the rule's sum `Σ± N_e(m ± g)ᵀ λ(m ± g) t L/2` splits exactly into
//! `t L [N_e(m)ᵀ λ(δ₀) + (N_e(g) − N_e(0))ᵀ λ(δ₁)]`: the same quadrature in half the work.
//!
//! The traction on a shared edge is one physical quantity, `+λ` on one side and `−λ` on the
//! other, so each interface computes it once and hands it to both its elements. The interfaces
//! are kept in the order of their lower element `a < b`; a sweep in that order has finished
//! element `e` once it has done the interfaces that start at `e` (those that end at `e` started
//! earlier). The element's force is then complete and, in a time step, its velocity and
//! displacement are advanced at once ([`ElementWise`] fuses eq. 15 with the update of
//! DESIGN.md §7): `U_e` is read by no later interface, and the step moves each vector once.
//!
//! Parallel sweeps run over fixed blocks of consecutive elements. An interface from one block
//! into a later one is computed before the sweeps, from the state at `t_n`, and handed to both
//! blocks. Every element sums its edges in interface order whatever the blocks and the threads,
//! so the result does not depend on the thread count.

use super::Evaluator;
use crate::formulation::{Kinematics, Springs};
use crate::geometry::Vec2;
use crate::mass::Update;
use crate::model::{Model, GROUND};
use crate::scene::EvaluatorKind;
use rayon::prelude::*;
use std::marker::PhantomData;
use std::ops::Range;
use std::sync::Mutex;

/// What one interface needs at evaluation time (80 bytes).
#[derive(Debug, Clone, Copy)]
struct Face {
    /// The lower element, and the higher one or [`GROUND`].
    a: u32,
    b: u32,
    /// The edge's midpoint from the centroids of `a` and `b` (m; `db` unused on ground).
    da: Vec2,
    db: Vec2,
    /// The springs times thickness and the rule's total weight, `t L S` (N/m).
    springs: Springs,
    /// The Gauss offset `g = L/(2√3) s` along the edge (m).
    g: Vec2,
}

/// Consecutive elements swept by one task, with the interfaces that start in them.
#[derive(Debug, Clone)]
struct Block {
    elements: Range<usize>,
    faces: Range<usize>,
    /// Interfaces into later blocks, as a range of `ElementWise::crossing`.
    outgoing: Range<usize>,
    /// Interfaces from earlier blocks, as a range of `ElementWise::incoming`.
    incoming: Range<usize>,
}

/// Elements per block: at least this many, and at most 64 blocks in all (fewer interfaces
/// cross blocks on large meshes).
const MIN_BLOCK: usize = 4096;
const MAX_BLOCKS: usize = 64;

/// Element-wise evaluation of eq. 15 for the kinematics `K` with `N` DOFs per element.
pub struct ElementWise<K: Kinematics<N>, const N: usize> {
    /// Sorted by `(a, b)`.
    faces: Vec<Face>,
    blocks: Vec<Block>,
    /// The interfaces whose elements lie in two blocks, in interface order.
    crossing: Vec<u32>,
    /// Per block, indices into `crossing` of the interfaces that end in it, in interface order.
    incoming: Vec<u32>,
    /// The forces of each crossing interface on its sides `a` and `b`, computed before the sweeps.
    crossing_forces: Mutex<Vec<[[f64; N]; 2]>>,
    /// `t A D` per element, acting on the strains `U_e[3..6]` (hybrid only; empty for rigid).
    interior: Vec<nalgebra::Matrix3<f64>>,
    kinematics: PhantomData<K>,
}

impl<K: Kinematics<N>, const N: usize> ElementWise<K, N> {
    /// Face records, blocks and crossing interfaces from the model's interfaces.
    pub fn new(model: &Model) -> Self {
        let t = model.thickness;
        let mut faces: Vec<Face> = model
            .interfaces
            .iter()
            .map(|i| {
                let ([g0, g1], _) = i.gauss_points();
                let (mid, tl) = (i.midpoint(), t * i.length);
                let offset = |e: u32| if e == GROUND { Vec2::zeros() } else { mid - model.elements[e as usize].props.centroid };
                // `S` is even in the normal and `λ` odd in `δ = u_b − u_a`: the sides may swap.
                let (a, b) = if i.b < i.a { (i.b, i.a) } else { (i.a, i.b) };
                Face { a, b, da: offset(a), db: offset(b), springs: Springs::new(i.normal, i.k_n * tl, i.k_s * tl), g: 0.5 * (g1 - g0) }
            })
            .collect();
        faces.sort_by_key(|f| (f.a, f.b));
        let n = model.elements.len();
        let len = MIN_BLOCK.max(n.div_ceil(MAX_BLOCKS));
        let block_of = |e: u32| e as usize / len;
        let crossing: Vec<u32> = (0..faces.len() as u32)
            .filter(|&k| {
                let f = &faces[k as usize];
                f.b != GROUND && block_of(f.b) != block_of(f.a)
            })
            .collect();
        let mut blocks = Vec::new();
        let mut incoming = Vec::new();
        for first in (0..n).step_by(len) {
            let elements = first..(first + len).min(n);
            let start = |e: usize| faces.partition_point(|f| (f.a as usize) < e);
            let out = |e: usize| crossing.partition_point(|&k| (faces[k as usize].a as usize) < e);
            let ends_here = (0..crossing.len()).filter(|&c| elements.contains(&(faces[crossing[c] as usize].b as usize)));
            let before = incoming.len();
            incoming.extend(ends_here.map(|c| c as u32));
            blocks.push(Block {
                faces: start(elements.start)..start(elements.end),
                outgoing: out(elements.start)..out(elements.end),
                incoming: before..incoming.len(),
                elements,
            });
        }
        let interior = if K::HAS_INTERIOR {
            model.elements.iter().map(|e| e.d * (model.thickness * e.props.area)).collect()
        } else {
            Vec::new()
        };
        let crossing_forces = Mutex::new(vec![[[0.0; N]; 2]; crossing.len()]);
        ElementWise { faces, blocks, crossing, incoming, crossing_forces, interior, kinematics: PhantomData }
    }

    /// The generalised forces that face `f` puts on its sides `a` and `b` (`ub = None` on
    /// ground): `± t L [N(m)ᵀ λ(δ₀) + (N(g) − N(0))ᵀ λ(δ₁)]` with `δ = u_b − u_a` (module doc).
    #[inline(always)]
    fn face_forces(&self, f: &Face, ua: &[f64; N], ub: Option<&[f64; N]>) -> [[f64; N]; 2] {
        let s = &f.springs;
        let mut delta = -K::displacement(ua, f.da);
        let mut out = [[0.0; N]; 2];
        let Some(ub) = ub else {
            K::add_force(&mut out[0], f.da, s.apply(delta));
            K::add_edge_odd(&mut out[0], ua, None, f.g, s);
            return out;
        };
        delta += K::displacement(ub, f.db);
        let traction = s.apply(delta);
        K::add_force(&mut out[0], f.da, traction);
        K::add_edge_odd(&mut out[0], ua, Some(ub), f.g, s);
        K::add_force(&mut out[1], f.db, -traction);
        K::add_edge_odd(&mut out[1], ub, Some(ua), f.g, s);
        out
    }

    /// The crossing interfaces' forces, from `u` at `t_n`, before any block moves.
    fn crossing_pass(&self, u: &[[f64; N]]) -> std::sync::MutexGuard<'_, Vec<[[f64; N]; 2]>> {
        let mut forces = self.crossing_forces.lock().unwrap_or_else(|e| e.into_inner());
        forces.par_iter_mut().zip(self.crossing.par_iter()).with_min_len(1024).for_each(|(out, &k)| {
            let f = &self.faces[k as usize];
            *out = self.face_forces(f, &u[f.a as usize], Some(&u[f.b as usize]));
        });
        forces
    }

    /// Eq. 15 over one block: `f` (the block's part) gains `f_int`, minus the springs' forces
    /// plus the interior term `t A D ε` of hybrid elements; each element is handed to `state`
    /// as soon as its force is complete. `crossing` holds the crossing interfaces' forces.
    #[inline(always)]
    fn sweep<S: BlockState<N>>(&self, block: &Block, crossing: &[[[f64; N]; 2]], f: &mut [[f64; N]], state: &mut S) {
        let first = block.elements.start;
        for &c in &self.incoming[block.incoming.clone()] {
            let b = self.faces[self.crossing[c as usize] as usize].b as usize;
            sub(&mut f[b - first], &crossing[c as usize][1]);
        }
        let mut out = block.outgoing.start;
        let mut k = block.faces.start;
        for e in block.elements.clone() {
            let i = e - first;
            while k < block.faces.end && self.faces[k].a as usize == e {
                let face = &self.faces[k];
                k += 1;
                if face.b == GROUND {
                    let [fa, _] = self.face_forces(face, state.u(i), None);
                    sub(&mut f[i], &fa);
                } else if (face.b as usize) < block.elements.end {
                    let j = face.b as usize - first;
                    let [fa, fb] = self.face_forces(face, state.u(i), Some(state.u(j)));
                    sub(&mut f[i], &fa);
                    sub(&mut f[j], &fb);
                } else {
                    sub(&mut f[i], &crossing[out][0]);
                    out += 1;
                }
            }
            if K::HAS_INTERIOR {
                let ue = state.u(i);
                let stress = self.interior[e] * nalgebra::Vector3::new(ue[3], ue[4], ue[5]);
                for j in 0..3 {
                    f[i][3 + j] += stress[j];
                }
            }
            state.complete(e, i, &mut f[i]);
        }
    }
}

#[inline(always)]
fn sub<const N: usize>(acc: &mut [f64; N], x: &[f64; N]) {
    for j in 0..N {
        acc[j] -= x[j];
    }
}

/// The state a sweep reads `U` from, and what it does with an element whose force is complete.
trait BlockState<const N: usize> {
    fn u(&self, i: usize) -> &[f64; N];
    /// Element `e` (index `i` in the block) has its whole force `f`.
    fn complete(&mut self, e: usize, i: usize, f: &mut [f64; N]);
}

/// An evaluation: `U` is only read, and the forces stay where they are.
struct Evaluate<'a, const N: usize>(&'a [[f64; N]]);

impl<const N: usize> BlockState<N> for Evaluate<'_, N> {
    #[inline(always)]
    fn u(&self, i: usize) -> &[f64; N] {
        &self.0[i]
    }
    #[inline(always)]
    fn complete(&mut self, _: usize, _: usize, _: &mut [f64; N]) {}
}

/// A time step: a complete element is advanced, and its force is cleared for the next step.
struct Advance<'a, const N: usize> {
    u: &'a mut [[f64; N]],
    v: &'a mut [[f64; N]],
    update: &'a Update<'a>,
}

impl<const N: usize> BlockState<N> for Advance<'_, N> {
    #[inline(always)]
    fn u(&self, i: usize) -> &[f64; N] {
        &self.u[i]
    }
    #[inline(always)]
    fn complete(&mut self, e: usize, i: usize, f: &mut [f64; N]) {
        self.update.element(e, f, &mut self.v[i], &mut self.u[i]);
        *f = [0.0; N];
    }
}

impl<K: Kinematics<N>, const N: usize> Evaluator for ElementWise<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::ElementWise
    }

    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        let crossing_forces = self.crossing.len() * std::mem::size_of::<[[f64; N]; 2]>();
        size_of_val(&self.faces[..]) + size_of_val(&self.crossing[..])
            + size_of_val(&self.incoming[..]) + size_of_val(&self.interior[..]) + crossing_forces
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        let crossing = self.crossing_pass(u);
        self.for_each_block(f, |block, f| {
            f.fill([0.0; N]);
            self.sweep(block, &crossing, f, &mut Evaluate(&u[block.elements.clone()]));
        });
    }

    fn fuses(&self) -> bool {
        true
    }

    fn advance(&self, u: &mut [f64], v: &mut [f64], force: &mut [f64], update: &Update) {
        let (u, _) = u.as_chunks_mut::<N>();
        let (v, _) = v.as_chunks_mut::<N>();
        let (f, _) = force.as_chunks_mut::<N>();
        let crossing = self.crossing_pass(u);
        let work = |(block, ((f, u), v)): (&Block, ((&mut [[f64; N]], &mut [[f64; N]]), &mut [[f64; N]]))| {
            self.sweep(block, &crossing, f, &mut Advance { u, v, update });
        };
        match &self.blocks[..] {
            [] => {}
            [block] => work((block, ((f, u), v))),
            blocks => {
                let len = blocks[0].elements.len();
                blocks.par_iter().zip(f.par_chunks_mut(len).zip(u.par_chunks_mut(len)).zip(v.par_chunks_mut(len))).for_each(work);
            }
        }
    }
}

impl<K: Kinematics<N>, const N: usize> ElementWise<K, N> {
    /// `work(block, f_block)` for every block, in parallel when there are several.
    fn for_each_block(&self, f: &mut [[f64; N]], work: impl Fn(&Block, &mut [[f64; N]]) + Sync + Send) {
        match &self.blocks[..] {
            [] => {}
            [block] => work(block, f),
            blocks => {
                let len = blocks[0].elements.len();
                blocks.par_iter().zip(f.par_chunks_mut(len)).for_each(|(block, f)| work(block, f));
            }
        }
    }
}
