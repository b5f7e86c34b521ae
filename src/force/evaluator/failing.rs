//! An evaluator's couplings with the failing interfaces they carry (`force::failure`): each
//! coupling adds its elastic forces, then return-maps the Gauss points of its failing interfaces
//! and adds their plastic part, in one pass of the sweep ([`super::sweep`]), evaluating or
//! stepping. An element-wise coupling carries its own interface when that one fails; an
//! assembled one (a block `K_ab`) the failing interfaces between its two elements.

use super::sweep::{Couplings, Face};
use crate::force::failure::{FailingInterfaces, FailureState, PlasticForces};
use crate::lanes::Lanes;
use crate::model::formulation::Kinematics;
use crate::model::Model;

/// Per coupling of an evaluator (in the order of its sweep), the failing interfaces it carries:
/// a range of [`Model::failing_interfaces`].
pub(super) struct Carried(Vec<[u32; 2]>);

impl Carried {
    /// The failing interfaces of each coupling between elements `(a, b)`, `a < b`, whose
    /// `interface` names the model interface it is (element-wise) or `None` for all those
    /// between its elements (assembled). Each failing interface goes to one coupling, the first
    /// that carries it.
    ///
    /// # Panics
    /// If a failing interface has no coupling: an evaluator that left out an interface between
    /// two elements.
    pub(super) fn new<R>(
        model: &Model,
        faces: &[Face<R>],
        interface: impl Fn(&Face<R>) -> Option<u32>,
    ) -> Self {
        let failing = model.failing_interfaces();
        let mut rank = vec![u32::MAX; model.interfaces.len()];
        for (j, &k) in failing.iter().enumerate() {
            rank[k as usize] = j as u32;
        }
        let pairs: Vec<(u32, u32)> = failing
            .iter()
            .map(|&k| {
                let i = &model.interfaces[k as usize];
                (i.a.min(i.b), i.a.max(i.b))
            })
            .collect();
        let mut taken = vec![false; failing.len()];
        let ranges = faces
            .iter()
            .map(|f| {
                let range = match interface(f) {
                    Some(k) => match rank[k as usize] {
                        u32::MAX => [0, 0],
                        j => [j, j + 1],
                    },
                    None => {
                        // The failing interfaces are sorted by their elements.
                        let start = pairs.partition_point(|&p| p < (f.a, f.b));
                        let end = start
                            + pairs[start..]
                                .iter()
                                .take_while(|&&p| p == (f.a, f.b))
                                .count();
                        [start as u32, end as u32]
                    }
                };
                let range = if taken[range[0] as usize..range[1] as usize]
                    .iter()
                    .any(|&t| t)
                {
                    [0, 0]
                } else {
                    range
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
        let failing = plastic
            .as_any()
            .downcast_ref::<FailingInterfaces<K, N>>()
            .expect("the failing interfaces of the evaluator's formulation");
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
