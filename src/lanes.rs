//! Arithmetic in groups of four lanes of `f64`, in the 256-bit registers of AVX2 where the
//! processor has them ([`pulp::x86::V3`]) and one number at a time elsewhere ([`Plain`]), with
//! the same bits on both: no fused multiply-add, and sums in the same order.
//!
//! Two layouts: the outputs of one interface in lanes ([`Lanes::combine`]), and four
//! consecutive elements in lanes, one group per DOF ([`Wide`], [`Lanes::combine_spread`]), which
//! the sweep uses where elements repeat their neighbours' interfaces, and in which whole vectors
//! may be stored ([`grouped`]).

/// Four consecutive elements in lanes: `w[j][l]` is DOF `j` of the `l`-th.
pub type Wide<const N: usize> = [[f64; 4]; N];

/// The DOFs of lane `l`.
#[inline(always)]
pub fn lane<const N: usize>(w: &Wide<N>, l: usize) -> [f64; N] {
    std::array::from_fn(|j| w[j][l])
}

/// Sets the DOFs of lane `l`.
#[inline(always)]
pub fn set_lane<const N: usize>(w: &mut Wide<N>, l: usize, x: &[f64; N]) {
    for j in 0..N {
        w[j][l] = x[j];
    }
}

/// Vectors of DOFs (`U`, `v`, a lumped `M⁻¹`) stored in groups of four elements: group `g` is
/// the [`Wide`] of elements `4g..4g + 4`, so that a sweep in lanes loads four elements' DOF
/// with no transpose. The last group is padded with zeros.
pub mod grouped {
    use super::Wide;
    use rayon::prelude::*;

    /// Groups per parallel task of [`group`] and [`ungroup`].
    const TASK: usize = 4096;

    /// Where DOF `d` of a vector with `nd` DOFs per element lies in its grouped form:
    /// DOF `j` of element `e` at `4 nd (e / 4) + 4 j + e % 4`.
    #[inline(always)]
    pub fn index(nd: usize, d: usize) -> usize {
        let (e, j) = (d / nd, d % nd);
        4 * nd * (e / 4) + 4 * j + e % 4
    }

    /// The length of the grouped form of `dofs` DOFs, `nd` per element.
    pub fn len(nd: usize, dofs: usize) -> usize {
        (dofs / nd).div_ceil(4) * 4 * nd
    }

    /// `out ← x` grouped, `nd` DOFs per element (3 or 6).
    pub fn group(nd: usize, x: &[f64], out: &mut [f64]) {
        match nd {
            3 => to_groups::<3>(x, out),
            _ => to_groups::<6>(x, out),
        }
    }

    /// `out ← x` from its grouped form: [`group`] undone.
    pub fn ungroup(nd: usize, x: &[f64], out: &mut [f64]) {
        match nd {
            3 => from_groups::<3>(x, out),
            _ => from_groups::<6>(x, out),
        }
    }

    /// A flat grouped vector (`N` DOFs per element) as its groups, one [`Wide`] per four
    /// elements; a tail short of a whole group is left out.
    #[inline(always)]
    pub fn as_groups<const N: usize>(x: &[f64]) -> &[Wide<N>] {
        x.as_chunks::<4>().0.as_chunks::<N>().0
    }

    /// [`as_groups`], mutable.
    #[inline(always)]
    pub fn as_groups_mut<const N: usize>(x: &mut [f64]) -> &mut [Wide<N>] {
        x.as_chunks_mut::<4>().0.as_chunks_mut::<N>().0
    }

    fn to_groups<const N: usize>(x: &[f64], g: &mut [f64]) {
        as_groups_mut::<N>(g)
            .par_chunks_mut(TASK)
            .zip(x.par_chunks(TASK * 4 * N))
            .for_each(|(g, x)| {
                for (g, x) in g.iter_mut().zip(x.chunks(4 * N)) {
                    for (l, x) in x.chunks(N).enumerate() {
                        for j in 0..N {
                            g[j][l] = x[j];
                        }
                    }
                }
            });
    }

    fn from_groups<const N: usize>(g: &[f64], x: &mut [f64]) {
        as_groups::<N>(g)
            .par_chunks(TASK)
            .zip(x.par_chunks_mut(TASK * 4 * N))
            .for_each(|(g, x): (&[Wide<N>], &mut [f64])| {
                for (g, x) in g.iter().zip(x.chunks_mut(4 * N)) {
                    for (l, x) in x.chunks_mut(N).enumerate() {
                        for j in 0..N {
                            x[j] = g[j][l];
                        }
                    }
                }
            });
    }
}

/// The columns `g` of [`Lanes::combine`] with each output `m` of column `k` in all four lanes,
/// for [`Lanes::combine_spread`].
pub fn spread<const M: usize, const Q: usize>(g: &[[[f64; 4]; Q]; M]) -> [[[f64; 4]; M]; M] {
    std::array::from_fn(|k| std::array::from_fn(|m| [g[k][m / 4][m % 4]; 4]))
}

/// Sums of products in groups of four lanes, `o = Σ_k x_k g[k]` in the order of `k`, with no
/// fused multiply-add: the same bits on every path.
pub trait Lanes: Copy {
    /// `o = Σ_k x_k g[k]`, the outputs in `Q` groups of four lanes.
    fn combine<const M: usize, const Q: usize>(
        self,
        g: &[[[f64; 4]; Q]; M],
        x: &[f64; M],
    ) -> [[f64; 4]; Q];

    /// The same sums for four inputs at once, input `k` of lane `l` being `x[k][l]`:
    /// `o[m] = Σ_k g[k][m] x[k]`, with `g[k][m]` output `m` of column `k` of
    /// [`Lanes::combine`] in all four lanes ([`spread`]): each product takes it from memory as
    /// it is.
    #[inline(always)]
    fn combine_spread<const M: usize>(self, g: &[[[f64; 4]; M]; M], x: &Wide<M>) -> Wide<M> {
        let mut o: Wide<M> = std::array::from_fn(|m| self.mul(g[0][m], x[0]));
        for k in 1..M {
            for m in 0..M {
                o[m] = self.add(o[m], self.mul(g[k][m], x[k]));
            }
        }
        o
    }

    /// `a + b`, lane by lane.
    #[inline(always)]
    fn add(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|l| a[l] + b[l])
    }

    /// `a − b`, lane by lane.
    #[inline(always)]
    fn sub(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|l| a[l] - b[l])
    }

    /// `−a`, lane by lane.
    #[inline(always)]
    fn neg(self, a: [f64; 4]) -> [f64; 4] {
        a.map(|a| -a)
    }

    /// `a b`, lane by lane.
    #[inline(always)]
    fn mul(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|l| a[l] * b[l])
    }

    /// `f` plus `o` moved up one lane, lane 0 plus lane 0 of `carry`; `carry` then holds `o`
    /// moved up one lane, its lane 3 in lane 0, for the next four elements.
    #[inline(always)]
    fn add_carried(self, f: [f64; 4], o: [f64; 4], carry: &mut [f64; 4]) -> [f64; 4] {
        let up = [o[3], o[0], o[1], o[2]];
        let sum = std::array::from_fn(|l| f[l] + if l == 0 { carry[0] } else { up[l] });
        *carry = up;
        sum
    }

    /// Four elements' DOFs in lanes.
    #[inline(always)]
    fn wide<const N: usize>(self, x: &[[f64; N]; 4]) -> Wide<N> {
        std::array::from_fn(|j| std::array::from_fn(|l| x[l][j]))
    }

    /// Each element's successor, for the four elements `a` followed by the four `n`: lanes 1–3
    /// of `a`, then lane 0 of `n`.
    #[inline(always)]
    fn shift<const N: usize>(self, a: &Wide<N>, n: &Wide<N>) -> Wide<N> {
        std::array::from_fn(|j| [a[j][1], a[j][2], a[j][3], n[j][0]])
    }

    /// Four elements' DOFs from lanes: [`Lanes::wide`] undone.
    #[inline(always)]
    fn narrow<const N: usize>(self, w: &Wide<N>) -> [[f64; N]; 4] {
        std::array::from_fn(|l| lane(w, l))
    }
}

/// [`Lanes`] one number at a time, on any processor.
#[derive(Clone, Copy)]
pub struct Plain;

impl Lanes for Plain {
    #[inline(always)]
    fn combine<const M: usize, const Q: usize>(
        self,
        g: &[[[f64; 4]; Q]; M],
        x: &[f64; M],
    ) -> [[f64; 4]; Q] {
        let mut o = [[0.0; 4]; Q];
        for q in 0..Q {
            for l in 0..4 {
                o[q][l] = g[0][q][l] * x[0];
            }
        }
        for k in 1..M {
            for q in 0..Q {
                for l in 0..4 {
                    o[q][l] += g[k][q][l] * x[k];
                }
            }
        }
        o
    }
}

/// [`Lanes`] in the 256-bit registers of AVX2.
#[cfg(target_arch = "x86_64")]
impl Lanes for pulp::x86::V3 {
    #[inline(always)]
    fn combine<const M: usize, const Q: usize>(
        self,
        g: &[[[f64; 4]; Q]; M],
        x: &[f64; M],
    ) -> [[f64; 4]; Q] {
        let mut o = [[0.0; 4]; Q];
        let x0 = self.splat_f64x4(x[0]);
        for q in 0..Q {
            o[q] = pulp::cast(self.mul_f64x4(pulp::cast(g[0][q]), x0));
        }
        for k in 1..M {
            let xk = self.splat_f64x4(x[k]);
            for q in 0..Q {
                let term = self.mul_f64x4(pulp::cast(g[k][q]), xk);
                o[q] = pulp::cast(self.add_f64x4(pulp::cast(o[q]), term));
            }
        }
        o
    }

    #[inline(always)]
    fn add(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        pulp::cast(self.add_f64x4(pulp::cast(a), pulp::cast(b)))
    }

    #[inline(always)]
    fn sub(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        pulp::cast(self.sub_f64x4(pulp::cast(a), pulp::cast(b)))
    }

    #[inline(always)]
    fn mul(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        pulp::cast(self.mul_f64x4(pulp::cast(a), pulp::cast(b)))
    }

    /// `o` moved up one lane by one permutation, its lane 0 taken from `carry` by one blend.
    #[inline(always)]
    fn add_carried(self, f: [f64; 4], o: [f64; 4], carry: &mut [f64; 4]) -> [f64; 4] {
        let up = self
            .avx2
            ._mm256_permute4x64_pd::<0b10_01_00_11>(pulp::cast(o));
        let moved = self.avx._mm256_blend_pd::<0b0001>(up, pulp::cast(*carry));
        *carry = pulp::cast(up);
        pulp::cast(self.avx._mm256_add_pd(pulp::cast(f), moved))
    }

    /// Three DOFs: the 12 numbers in three registers, regrouped by two blends and a swap of
    /// halves, then three shuffles.
    #[inline(always)]
    fn wide<const N: usize>(self, x: &[[f64; N]; 4]) -> Wide<N> {
        use std::arch::x86_64::__m256d;
        if N != 3 {
            return Plain.wide(x);
        }
        let x = x.as_flattened();
        let load =
            |k: usize| -> __m256d { pulp::cast(<[f64; 4]>::try_from(&x[k..k + 4]).unwrap()) };
        let (a0, a1, a2) = (load(0), load(4), load(8));
        let avx = self.avx;
        // The pairs (x0 y0 | x2 y2), (θ0 x1 | θ2 x3), (y1 θ1 | y3 θ3).
        let u = avx._mm256_blend_pd::<0b1100>(a0, a1);
        let v = avx._mm256_permute2f128_pd::<0x21>(a0, a2);
        let w = avx._mm256_blend_pd::<0b1100>(a1, a2);
        let dofs = [
            avx._mm256_shuffle_pd::<0b1010>(u, v),
            avx._mm256_shuffle_pd::<0b0101>(u, w),
            avx._mm256_shuffle_pd::<0b1010>(v, w),
        ];
        std::array::from_fn(|j| pulp::cast(dofs[j]))
    }

    #[inline(always)]
    fn narrow<const N: usize>(self, w: &Wide<N>) -> [[f64; N]; 4] {
        use std::arch::x86_64::__m256d;
        if N != 3 {
            return Plain.narrow(w);
        }
        let dof = |j: usize| -> __m256d { pulp::cast(w[j]) };
        let (x, y, t) = (dof(0), dof(1), dof(2));
        let avx = self.avx;
        let p0 = avx._mm256_shuffle_pd::<0b0000>(x, y);
        let p1 = avx._mm256_shuffle_pd::<0b1010>(t, x);
        let p2 = avx._mm256_shuffle_pd::<0b1111>(y, t);
        let parts: [[f64; 4]; 3] = [
            pulp::cast(avx._mm256_permute2f128_pd::<0x20>(p0, p1)),
            pulp::cast(avx._mm256_blend_pd::<0b1100>(p2, p0)),
            pulp::cast(avx._mm256_permute2f128_pd::<0x31>(p1, p2)),
        ];
        let flat = parts.as_flattened();
        std::array::from_fn(|l| std::array::from_fn(|j| flat[N * l + j]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers of all signs and scales, zeros of both signs among them.
    fn numbers<const K: usize>(seed: usize) -> [f64; K] {
        std::array::from_fn(|k| match (k + seed) % 7 {
            0 => 0.0,
            1 => -0.0,
            i => (i as f64 - 3.5) * 10f64.powi(((k * 31 + seed) % 9) as i32 - 4) / 3.0,
        })
    }

    /// Three DOFs of four elements go into lanes and back unchanged, and the lanes are those
    /// of the plain build; the arithmetic of AVX2 in lanes has the plain build's bits,
    /// [`Lanes::combine_spread`] those of [`Lanes::combine`] lane by lane.
    #[test]
    fn the_lanes_of_avx2_are_the_plain_bits() {
        fn check(lanes: impl Lanes) {
            let bits = |w: &[f64]| w.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            for seed in 0..20 {
                let x: [[f64; 3]; 4] = std::array::from_fn(|l| numbers(seed + 3 * l));
                let w = lanes.wide(&x);
                assert_eq!(bits(w.as_flattened()), bits(Plain.wide(&x).as_flattened()));
                assert_eq!(w[1][2], x[2][1]);
                assert_eq!(
                    bits(lanes.narrow(&w).as_flattened()),
                    bits(x.as_flattened())
                );
                let (a, b) = (numbers::<4>(seed), numbers::<4>(seed + 5));
                for (fast, plain) in [
                    (lanes.add(a, b), Plain.add(a, b)),
                    (lanes.sub(a, b), Plain.sub(a, b)),
                    (lanes.mul(a, b), Plain.mul(a, b)),
                    (lanes.neg(a), Plain.neg(a)),
                ] {
                    assert_eq!(bits(&fast), bits(&plain));
                }
                let (c, d) = (numbers::<4>(seed + 2), numbers::<4>(seed + 9));
                let (mut fast_carry, mut plain_carry) = (d, d);
                assert_eq!(
                    bits(&lanes.add_carried(a, c, &mut fast_carry)),
                    bits(&Plain.add_carried(a, c, &mut plain_carry))
                );
                assert_eq!(bits(&fast_carry), bits(&plain_carry));
                let sum = Plain.add_carried(a, b, &mut plain_carry);
                assert_eq!((sum[0], sum[2]), (a[0] + c[3], a[2] + b[1]));
                assert_eq!(plain_carry, [b[3], b[0], b[1], b[2]]);
                // A 4 × 4 map, columns `g[k]`, applied to four inputs at once and one by one.
                let g: [[[f64; 4]; 1]; 4] = std::array::from_fn(|k| [numbers(seed + 11 * k)]);
                let inputs: Wide<4> = std::array::from_fn(|k| numbers(seed + 7 * k + 1));
                let o = lanes.combine_spread(&spread(&g), &inputs);
                for l in 0..4 {
                    let one = lanes.combine(&g, &lane(&inputs, l));
                    assert_eq!(bits(&lane(&o, l)), bits(&one[0]));
                }
            }
        }
        check(Plain);
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            check(simd);
        }
    }
}
