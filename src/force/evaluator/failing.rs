//! The assembled evaluator's couplings with the failing interfaces they carry
//! (`force::failure`): each block `K_ab` adds its elastic forces, then return-maps the Gauss
//! points of the failing interfaces between its two elements and adds their plastic part, in
//! one pass of the sweep ([`super::sweep`]), evaluating or stepping. (The element-wise
//! evaluator gives a failing interface its whole traction through its law instead,
//! `super::element_wise`.)

use super::sweep::{Couplings, Face};
use crate::force::failure::{FailingInterfaces, FailureState, PlasticForces};
use crate::lanes::Lanes;
use crate::model::formulation::Kinematics;
use crate::model::Model;

/// Per coupling of the assembled evaluator (in the order of its sweep), the failing interfaces
/// it carries: a range of [`Model::failing_interfaces`].
pub(super) struct Carried(Vec<[u32; 2]>);

impl Carried {
    /// The failing interfaces between the elements `(a, b)`, `a < b`, of each coupling (a
    /// block `K_ab`).
    ///
    /// # Panics
    /// If a failing interface has no coupling: an evaluator that left out a pair of elements
    /// with an interface between them.
    pub(super) fn new<R>(model: &Model, faces: &[Face<R>]) -> Self {
        let pairs: Vec<(u32, u32)> = model
            .failing_interfaces()
            .iter()
            .map(|&k| {
                let i = &model.interfaces[k as usize];
                (i.a.min(i.b), i.a.max(i.b))
            })
            .collect();
        let mut taken = vec![false; pairs.len()];
        let ranges = faces
            .iter()
            .map(|f| {
                // The failing interfaces are sorted by their elements.
                let start = pairs.partition_point(|&p| p < (f.a, f.b));
                let end = start
                    + pairs[start..]
                        .iter()
                        .take_while(|&&p| p == (f.a, f.b))
                        .count();
                let range = if taken[start..end].iter().any(|&t| t) {
                    [0, 0]
                } else {
                    [start as u32, end as u32]
                };
                taken[range[0] as usize..range[1] as usize].fill(true);
                range
            })
            .collect();
        assert!(
            taken.iter().all(|&t| t),
            "every failing interface lies in a coupling"
        );
        Carried(ranges)
    }
}

/// The failing interfaces `plastic` as those of the formulation `K`.
///
/// # Panics
/// If they are of another formulation.
pub(super) fn failing_of<K: Kinematics<N>, const N: usize>(
    plastic: &dyn PlasticForces,
) -> &FailingInterfaces<K, N> {
    plastic
        .as_any()
        .downcast_ref::<FailingInterfaces<K, N>>()
        .expect("the failing interfaces of the evaluator's formulation")
}

/// Couplings `C` with the failing interfaces they carry, for one sweep that updates `state`.
pub(super) struct WithFailure<'a, C, K: Kinematics<N>, const N: usize> {
    couplings: &'a C,
    carried: &'a [[u32; 2]],
    failing: &'a FailingInterfaces<K, N>,
    state: &'a FailureState,
}

impl<'a, C: Couplings<N>, K: Kinematics<N>, const N: usize> WithFailure<'a, C, K, N> {
    /// `couplings` with what they carry, the failing interfaces `plastic` (of the formulation
    /// `K`) in `state`.
    ///
    /// # Panics
    /// If the evaluator was built for a model whose interfaces do not fail (no `carried`), or
    /// `plastic` is not of the formulation `K`, or `carried` not of `couplings`.
    pub(super) fn new(
        couplings: &'a C,
        carried: Option<&'a Carried>,
        plastic: &'a dyn PlasticForces,
        state: &'a mut FailureState,
    ) -> Self {
        let failing = failing_of::<K, N>(plastic);
        let carried = carried.expect("an evaluator built for a model whose interfaces fail");
        assert_eq!(carried.0.len(), couplings.faces().len());
        WithFailure {
            couplings,
            carried: &carried.0,
            failing,
            state,
        }
    }

    /// Where `face` is in the couplings' faces.
    #[inline(always)]
    fn index(&self, face: &Face<C::Ref>) -> usize {
        let first = self.couplings.faces().as_ptr() as usize;
        (std::ptr::from_ref(face) as usize - first) / std::mem::size_of::<Face<C::Ref>>()
    }
}

impl<C: Couplings<N>, K: Kinematics<N>, const N: usize> Couplings<N> for WithFailure<'_, C, K, N> {
    type Ref = C::Ref;
    const PREFETCH: bool = C::PREFETCH;
    /// The evaluators find no runs where interfaces fail: each coupling is met on its own.
    const RUNS: bool = false;
    const WIDE: bool = false;
    const OWN: bool = C::OWN;
    #[inline(always)]
    fn faces(&self) -> &[Face<C::Ref>] {
        self.couplings.faces()
    }
    type Coupling<'b>
        = (C::Coupling<'b>, [u32; 2])
    where
        Self: 'b;
    /// The sweep names a coupling by its place in [`Couplings::faces`] (a reference into it),
    /// which gives the failing interfaces it carries.
    #[inline(always)]
    fn coupling<'b>(&'b self, face: &'b Face<C::Ref>) -> Self::Coupling<'b> {
        (
            self.couplings.coupling(face),
            self.carried[self.index(face)],
        )
    }
    #[inline(always)]
    fn add_pair(
        &self,
        lanes: impl Lanes,
        (coupling, [start, end]): (C::Coupling<'_>, [u32; 2]),
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        self.couplings.add_pair(lanes, coupling, ua, ub, fa, fb);
        if start < end {
            // A sweep computes each coupling once, and `Carried` gives each failing interface
            // to one coupling.
            let range = start as usize..end as usize;
            self.failing.couple(range, self.state, (ua, ub), fa, fb);
        }
    }
    #[inline(always)]
    fn add_ground(&self, face: &Face<C::Ref>, ua: &[f64; N], fa: &mut [f64; N]) {
        self.couplings.add_ground(face, ua, fa);
    }
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]) {
        self.couplings.add_own(e, ue, f);
    }
}
