//! Polygon geometry: area, centroid and second moments of a simple polygon (shoelace formulas).

use nalgebra::Vector2;

/// A point or vector in the plane (m).
pub type Vec2 = Vector2<f64>;

/// Area properties of a polygon; the moments are about its centroid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AreaProperties {
    /// Signed area (m²): positive for counter-clockwise vertices.
    pub area: f64,
    /// Centroid (m).
    pub centroid: Vec2,
    /// `∫ Δy² dA` about the centroid (m⁴).
    pub i_xx: f64,
    /// `∫ Δx² dA` about the centroid (m⁴).
    pub i_yy: f64,
    /// `∫ Δx Δy dA` about the centroid (m⁴).
    pub i_xy: f64,
}

impl AreaProperties {
    /// Polar moment of area about the centroid, `I_p = I_xx + I_yy` (m⁴).
    pub fn polar(&self) -> f64 {
        self.i_xx + self.i_yy
    }
}

/// Area, centroid and central second moments of the polygon `pts` (closed implicitly).
///
/// Computed relative to the first vertex to keep round-off independent of where the polygon lies.
pub fn area_properties(pts: &[Vec2]) -> AreaProperties {
    let o = pts[0];
    let (mut a2, mut cx, mut cy, mut ixx, mut iyy, mut ixy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..pts.len() {
        let p = pts[i] - o;
        let q = pts[(i + 1) % pts.len()] - o;
        let c = p.x * q.y - q.x * p.y;
        a2 += c;
        cx += (p.x + q.x) * c;
        cy += (p.y + q.y) * c;
        ixx += (p.y * p.y + p.y * q.y + q.y * q.y) * c;
        iyy += (p.x * p.x + p.x * q.x + q.x * q.x) * c;
        ixy += (p.x * q.y + 2.0 * p.x * p.y + 2.0 * q.x * q.y + q.x * p.y) * c;
    }
    let area = 0.5 * a2;
    let c = Vec2::new(cx / (3.0 * a2), cy / (3.0 * a2));
    // Moments about the first vertex, then shifted to the centroid (parallel-axis theorem).
    let (ixx0, iyy0, ixy0) = (ixx / 12.0, iyy / 12.0, ixy / 24.0);
    AreaProperties {
        area,
        centroid: o + c,
        i_xx: ixx0 - area * c.y * c.y,
        i_yy: iyy0 - area * c.x * c.x,
        i_xy: ixy0 - area * c.x * c.y,
    }
}

/// Twice the signed area of the triangle `a b c` (positive when counter-clockwise).
pub fn cross3(a: Vec2, b: Vec2, c: Vec2) -> f64 {
    (b - a).perp(&(c - a))
}

/// Whether the open segments `p1 p2` and `q1 q2` cross at a single interior point.
pub fn segments_cross(p1: Vec2, p2: Vec2, q1: Vec2, q2: Vec2) -> bool {
    let d1 = cross3(q1, q2, p1);
    let d2 = cross3(q1, q2, p2);
    let d3 = cross3(p1, p2, q1);
    let d4 = cross3(p1, p2, q2);
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

/// Distance from `x` to the segment `a b`.
pub fn point_segment_distance(x: Vec2, a: Vec2, b: Vec2) -> f64 {
    let d = b - a;
    let len2 = d.norm_squared();
    let s = if len2 > 0.0 {
        ((x - a).dot(&d) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + s * d - x).norm()
}

/// Distance between the segments `p1 p2` and `q1 q2` (0 when they cross).
pub fn segment_distance(p1: Vec2, p2: Vec2, q1: Vec2, q2: Vec2) -> f64 {
    if segments_cross(p1, p2, q1, q2) {
        return 0.0;
    }
    [
        point_segment_distance(p1, q1, q2),
        point_segment_distance(p2, q1, q2),
        point_segment_distance(q1, p1, p2),
        point_segment_distance(q2, p1, p2),
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min)
}

/// Whether `x` lies strictly inside the polygon `pts` (even-odd rule).
pub fn point_in_polygon(x: Vec2, pts: &[Vec2]) -> bool {
    let mut inside = false;
    let n = pts.len();
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        if (a.y > x.y) != (b.y > x.y) {
            let xc = a.x + (x.y - a.y) * (b.x - a.x) / (b.y - a.y);
            if x.x < xc {
                inside = !inside;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn rectangle_properties_match_closed_form() {
        let (b, h) = (3.0, 2.0);
        let pts = [
            Vec2::new(1.0, 5.0),
            Vec2::new(1.0 + b, 5.0),
            Vec2::new(1.0 + b, 5.0 + h),
            Vec2::new(1.0, 5.0 + h),
        ];
        let p = area_properties(&pts);
        assert_relative_eq!(p.area, b * h, max_relative = 1e-14);
        assert_relative_eq!(p.centroid, Vec2::new(2.5, 6.0), max_relative = 1e-14);
        assert_relative_eq!(p.i_xx, b * h.powi(3) / 12.0, max_relative = 1e-13);
        assert_relative_eq!(p.i_yy, h * b.powi(3) / 12.0, max_relative = 1e-13);
        assert!(p.i_xy.abs() < 1e-12);
    }

    #[test]
    fn right_triangle_product_moment_matches_closed_form() {
        // Legs b along x and h along y: I_xy about the centroid = -b² h² / 72.
        let (b, h) = (2.0, 3.0);
        let p = area_properties(&[Vec2::new(0.0, 0.0), Vec2::new(b, 0.0), Vec2::new(0.0, h)]);
        assert_relative_eq!(p.i_xy, -b * b * h * h / 72.0, max_relative = 1e-13);
        assert_relative_eq!(p.i_xx, b * h.powi(3) / 36.0, max_relative = 1e-13);
    }
}
