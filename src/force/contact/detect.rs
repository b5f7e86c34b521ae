//! The geometry of a contact (eqs. 17–20): whether the path of a vertex over a step crosses an
//! edge, where, and the gap of the vertex relative to that crossing point.

use crate::mesh::geometry::Vec2;

/// `(a_x b_y − a_y b_x)`, the scalar cross product.
#[inline(always)]
fn cross(a: Vec2, b: Vec2) -> f64 {
    a.perp(&b)
}

/// Eqs. 18–20: the path `p → m` of a vertex over one step enters the edge `b1 → b2` (whose solid
/// side is on its left, `t > 0` outside) when
/// - it ends strictly inside, `t_m < 0`, having started outside or on the edge line, `t_p ≥ 0`
///   (eq. 19 asks `t_p t_m < 0`; a start on the line is allowed so that bodies placed exactly
///   touching are caught when they first press), and
/// - it passes between the end points, `t_b1 t_b2 ≤ 0` with `t_b1 ≠ t_b2` (the end points
///   themselves count, so that a corner landing exactly on a corner is caught).
///
/// Returns the crossing point `c = b1 + λ (b2 − b1)` as `λ = S1 / (S1 + S2)` (eq. 20), with
/// `S1`, `S2` the areas of the triangles `p m b1` and `p m b2`.
#[inline]
pub fn entry(p: Vec2, m: Vec2, b1: Vec2, b2: Vec2) -> Option<f64> {
    let t_p = cross(b1 - b2, p - b1);
    let t_m = cross(b1 - b2, m - b1);
    if !(t_p >= 0.0 && t_m < 0.0) {
        return None;
    }
    let t_b1 = cross(p - m, b1 - p);
    let t_b2 = cross(p - m, b2 - p);
    if t_b1 * t_b2 <= 0.0 && t_b1 != t_b2 {
        let (s1, s2) = (t_b1.abs(), t_b2.abs());
        Some(s1 / (s1 + s2))
    } else {
        None
    }
}

/// A vertex `m` against an edge `b1 → b2` whose solid side is on its left, as on a
/// counter-clockwise boundary (outward normal `n = (s_y, −s_x)`).
#[derive(Debug, Clone, Copy)]
pub struct Gap {
    /// Normal penetration `δ_n` (m), positive inside (eq. 17).
    pub normal: f64,
    /// Tangential slip `δ_s` (m) from the crossing point `c`, along `s = (b2 − b1)/L_b` (eq. 17).
    pub tangential: f64,
    /// Where `m` projects on the edge, as a fraction of `b1 → b2` (inside the edge: 0 … 1).
    pub along: f64,
}

/// The edge's unit tangent `s`, outward normal `n` and length.
#[inline]
pub fn frame(b1: Vec2, b2: Vec2) -> (Vec2, Vec2, f64) {
    let d = b2 - b1;
    let l = d.norm();
    let s = d / l;
    (s, Vec2::new(s.y, -s.x), l)
}

/// Eq. 17 for a vertex at `m` whose contact started at `c = b1 + λ (b2 − b1)`: `δ_n` is the
/// depth below the edge line (the paper's `(m − c) · (−s_y, s_x)`), `δ_s = (m − c) · s`.
#[inline]
pub fn gap(m: Vec2, b1: Vec2, b2: Vec2, lambda: f64) -> Gap {
    let (s, n, l) = frame(b1, b2);
    let c = b1 + lambda * (b2 - b1);
    Gap {
        normal: -(m - c).dot(&n),
        tangential: (m - c).dot(&s),
        along: (m - b1).dot(&s) / l,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64) -> Vec2 {
        Vec2::new(x, y)
    }

    // Ground from (1, 0) to (−1, 0): solid below (on the left of b1 → b2), free side above.
    const B1: (f64, f64) = (1.0, 0.0);
    const B2: (f64, f64) = (-1.0, 0.0);

    #[test]
    fn a_vertex_falling_through_the_edge_enters_at_the_crossing_point() {
        let (b1, b2) = (v(B1.0, B1.1), v(B2.0, B2.1));
        // From (0.5, 0.1) to (0.3, −0.1): crosses y = 0 at x = 0.4, λ = (1 − 0.4)/2 = 0.3.
        let lambda = entry(v(0.5, 0.1), v(0.3, -0.1), b1, b2).expect("crosses");
        assert!((lambda - 0.3).abs() < 1e-15, "λ = {lambda}");
        let g = gap(v(0.3, -0.1), b1, b2, lambda);
        assert!(
            (g.normal - 0.1).abs() < 1e-15 && (g.tangential - 0.1).abs() < 1e-15,
            "{g:?}"
        );
        assert!((g.along - 0.35).abs() < 1e-15);
    }

    #[test]
    fn no_entry_when_leaving_passing_beside_or_staying_outside() {
        let (b1, b2) = (v(B1.0, B1.1), v(B2.0, B2.1));
        assert!(
            entry(v(0.3, -0.1), v(0.5, 0.1), b1, b2).is_none(),
            "leaving the solid"
        );
        assert!(
            entry(v(1.5, 0.1), v(1.5, -0.1), b1, b2).is_none(),
            "beside the edge"
        );
        assert!(
            entry(v(0.0, 0.2), v(0.0, 0.1), b1, b2).is_none(),
            "still outside"
        );
        assert!(
            entry(v(0.0, -0.1), v(0.0, -0.2), b1, b2).is_none(),
            "already inside"
        );
    }

    #[test]
    fn starts_on_the_line_and_corners_count() {
        let (b1, b2) = (v(B1.0, B1.1), v(B2.0, B2.1));
        assert_eq!(
            entry(v(0.0, 0.0), v(0.0, -1e-9), b1, b2),
            Some(0.5),
            "touching, then pressing"
        );
        assert_eq!(
            entry(v(1.0, 0.1), v(1.0, -0.1), b1, b2),
            Some(0.0),
            "through the end point b1"
        );
        assert!(
            entry(v(0.0, 0.0), v(0.5, 0.0), b1, b2).is_none(),
            "sliding along the line"
        );
    }
}
