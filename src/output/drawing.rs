//! Dependency-free SVG pictures of a model, written as plain text: the elements with their
//! interfaces, supports and loads ([`model_svg`]), the elements displaced by a DOF vector
//! such as a mode shape ([`displaced_svg`]), or a run's final state with its cracks
//! ([`state_svg`]). Made for the README and for teaching, so every
//! mark is one of the model's objects: an interface is drawn as its two springs, centroid to
//! edge midpoint (the lengths `h_a`, `h_b` of eq. 12).

use crate::error::{Error, Result};
use crate::force::failure::InterfaceStatus;
use crate::mesh::geometry::Vec2;
use crate::model::{Model, GROUND};
use std::fmt::Write;

/// Fill colours of the bodies, in body order (repeated when there are more bodies).
const BODY_FILLS: [&str; 6] = [
    "#dbe7f3", "#f6e3c8", "#dcefd9", "#f2d9e6", "#e6e0f3", "#f3f0c8",
];

/// Maps model coordinates (m, y up) to pixels (y down) and collects the SVG elements.
struct Canvas {
    lo: Vec2,
    scale: f64,
    margin: f64,
    height: f64,
    width: f64,
    body: String,
}

impl Canvas {
    /// A canvas that shows every point of `points` at most `max_px` pixels wide or high, with
    /// room for a caption above.
    fn fit(points: impl Iterator<Item = Vec2>, max_px: f64) -> Canvas {
        let (mut lo, mut hi) = (Vec2::repeat(f64::MAX), Vec2::repeat(f64::MIN));
        for p in points {
            lo = lo.inf(&p);
            hi = hi.sup(&p);
        }
        let size = (hi - lo).map(|s| s.max(1e-12));
        let scale = (max_px / size.x).min(max_px / size.y);
        let margin = 48.0;
        Canvas {
            lo,
            scale,
            margin,
            width: size.x * scale + 2.0 * margin,
            height: size.y * scale + 2.0 * margin + 20.0,
            body: String::new(),
        }
    }

    fn px(&self, p: Vec2) -> (f64, f64) {
        let x = self.margin + (p.x - self.lo.x) * self.scale;
        let y = self.height - self.margin - (p.y - self.lo.y) * self.scale;
        (x, y)
    }

    fn polygon(&mut self, points: &[Vec2], style: &str) {
        let mut coords = String::new();
        for &p in points {
            let (x, y) = self.px(p);
            let _ = write!(coords, "{x:.2},{y:.2} ");
        }
        let _ = writeln!(
            self.body,
            r#"<polygon points="{}" {style}/>"#,
            coords.trim_end()
        );
    }

    fn line(&mut self, a: Vec2, b: Vec2, style: &str) {
        let ((x1, y1), (x2, y2)) = (self.px(a), self.px(b));
        let _ = writeln!(
            self.body,
            r#"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" {style}/>"#
        );
    }

    /// A line from `from` of `len_px` pixels along `dir` (model axes), with an arrow head.
    fn arrow(&mut self, from: Vec2, dir: Vec2, len_px: f64, colour: &str) {
        let (x, y) = self.px(from);
        self.arrow_px(x, y, dir, len_px, colour);
    }

    /// [`Canvas::arrow`] from the pixel `(x1, y1)`.
    fn arrow_px(&mut self, x1: f64, y1: f64, dir: Vec2, len_px: f64, colour: &str) {
        let d = (dir.x, -dir.y);
        let (x2, y2) = (x1 + d.0 * len_px, y1 + d.1 * len_px);
        let (hx, hy) = (x2 - d.0 * 7.0, y2 - d.1 * 7.0);
        let _ = writeln!(
            self.body,
            r#"<line x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke="{colour}" stroke-width="1.6"/><polygon points="{x2:.2},{y2:.2} {:.2},{:.2} {:.2},{:.2}" fill="{colour}"/>"#,
            hx - d.1 * 3.5,
            hy + d.0 * 3.5,
            hx + d.1 * 3.5,
            hy - d.0 * 3.5
        );
    }

    /// A grounded segment: the segment, and short hatch marks on the side of `outward`.
    fn ground(&mut self, p1: Vec2, p2: Vec2, outward: Vec2, colour: &str) {
        self.line(p1, p2, &format!(r#"stroke="{colour}" stroke-width="2.5""#));
        let len_px = (p2 - p1).norm() * self.scale;
        let marks = (len_px / 8.0).floor().max(1.0) as usize;
        let t = (p2 - p1).normalize();
        let hatch = (outward + t).normalize() * (6.0 / self.scale);
        for i in 0..marks {
            let p = p1 + (p2 - p1) * ((i as f64 + 0.5) / marks as f64);
            self.line(
                p,
                p + hatch,
                &format!(r#"stroke="{colour}" stroke-width="1""#),
            );
        }
    }

    fn text(&mut self, x: f64, y: f64, size: f64, text: &str) {
        let text = text
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;");
        let _ = writeln!(
            self.body,
            r#"<text x="{x:.1}" y="{y:.1}" font-family="sans-serif" font-size="{size}">{text}</text>"#
        );
    }

    fn finish(self) -> String {
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w:.0}\" height=\"{h:.0}\" \
                viewBox=\"0 0 {w:.0} {h:.0}\">\n<rect width=\"100%\" height=\"100%\" \
                fill=\"white\"/>\n{}</svg>\n",
            self.body,
            w = self.width,
            h = self.height
        )
    }
}

/// Every element as `(body, its vertices, at(e, x) of each vertex x)`.
pub(super) fn element_polygons(
    model: &Model,
    at: impl Fn(usize, Vec2) -> Vec2,
) -> Vec<(usize, Vec<Vec2>, Vec<Vec2>)> {
    let mut polygons = Vec::with_capacity(model.elements.len());
    for (b, body) in model.bodies.iter().enumerate() {
        for c in 0..body.mesh.n_cells() {
            let e = body.first_element + c;
            let vertices: Vec<Vec2> = body
                .mesh
                .cell(c)
                .iter()
                .map(|&k| body.mesh.vertices[k as usize])
                .collect();
            let mapped = vertices.iter().map(|&x| at(e, x)).collect();
            polygons.push((b, vertices, mapped));
        }
    }
    polygons
}

/// The displacement `N_e(x) U_e` of element `e` at `x` (`u`: `ndof` per element).
pub(super) fn displacement<'a>(
    model: &'a Model,
    u: &'a [f64],
) -> impl Fn(usize, Vec2) -> Vec2 + 'a {
    let nd = model.formulation.ndof();
    move |e, x| {
        model.formulation.displacement(
            &u[e * nd..(e + 1) * nd],
            x - model.elements[e].props.centroid,
        )
    }
}

/// The vertices of the model's bodies.
fn body_vertices(model: &Model) -> impl Iterator<Item = Vec2> + '_ {
    model
        .bodies
        .iter()
        .flat_map(|b| b.mesh.vertices.iter().copied())
}

/// The least and the largest coordinates of `points`.
fn extent(points: impl Iterator<Item = Vec2>) -> (Vec2, Vec2) {
    points.fold(
        (Vec2::repeat(f64::MAX), Vec2::repeat(f64::MIN)),
        |(lo, hi), p| (lo.inf(&p), hi.sup(&p)),
    )
}

/// The ground segments near the bodies whose extent is `(lo, hi)`: each clipped, along its
/// longer axis, to that extent widened by its larger side at both ends, so that 40 m of
/// ground under a 0.2 m brick is drawn as 0.6 m of it rather than shrinking the brick to a
/// dash; a segment wholly outside is left out.
fn ground_near(ground: &[[Vec2; 2]], (lo, hi): (Vec2, Vec2)) -> Vec<[Vec2; 2]> {
    let reach = (hi - lo).max();
    ground
        .iter()
        .filter_map(|&[p1, p2]| {
            let d = p2 - p1;
            let k = if d.x.abs() >= d.y.abs() { 0 } else { 1 };
            if d[k] == 0.0 {
                return None;
            }
            let at = |x: f64| (x - p1[k]) / d[k];
            let (a, b) = (at(lo[k] - reach), at(hi[k] + reach));
            let (t0, t1) = (a.min(b).max(0.0), a.max(b).min(1.0));
            (t0 < t1).then(|| [p1 + d * t0, p1 + d * t1])
        })
        .collect()
}

/// Draws `ground` (segments) hatched on the side away from the bodies (clockwise normal, as
/// a scene's ground faces its bodies on the left of `from → to`).
fn draw_ground(cv: &mut Canvas, ground: &[[Vec2; 2]]) {
    for g in ground {
        let t = (g[1] - g[0]).normalize();
        cv.ground(g[0], g[1], Vec2::new(t.y, -t.x), "#000");
    }
}

/// The model as built from its scene: elements (one fill per body), each interface as its two
/// springs from the centroids to the edge midpoint (blue), ground springs as hatched edges
/// (green), elements with fixed DOFs marked by a black triangle at the centroid, point loads as
/// red arrows (length by magnitude), gravity as an arrow in the corner and contact ground as
/// hatched black segments. About 800 pixels on its longer side.
pub fn model_svg(model: &Model) -> String {
    let ground = ground_near(&model.ground, extent(body_vertices(model)));
    let mut cv = Canvas::fit(
        body_vertices(model).chain(ground.iter().flatten().copied()),
        800.0,
    );
    for (b, vertices, _) in element_polygons(model, |_, x| x) {
        let fill = BODY_FILLS[b % BODY_FILLS.len()];
        cv.polygon(
            &vertices,
            &format!(r##"fill="{fill}" stroke="#555" stroke-width="0.6""##),
        );
    }
    let thin = model.interfaces.len() > 5000;
    let spring = format!(
        r##"stroke="#2a5db0" stroke-width="{}""##,
        if thin { 0.3 } else { 0.8 }
    );
    for i in &model.interfaces {
        let (m, xa) = (i.midpoint(), model.elements[i.a as usize].props.centroid);
        if i.b == GROUND {
            cv.ground(i.p1, i.p2, i.normal, "#1b8a3a");
        } else {
            cv.line(xa, m, &spring);
            cv.line(m, model.elements[i.b as usize].props.centroid, &spring);
        }
    }
    draw_ground(&mut cv, &ground);
    let nd = model.formulation.ndof();
    let mut marked = usize::MAX;
    for &dof in &model.fixed {
        let e = dof / nd;
        if e != marked {
            marked = e;
            let (x, y) = cv.px(model.elements[e].props.centroid);
            let _ = writeln!(
                cv.body,
                r#"<polygon points="{x:.2},{y:.2} {:.2},{:.2} {:.2},{:.2}" fill="black"/>"#,
                x - 4.0,
                y + 7.0,
                x + 4.0,
                y + 7.0
            );
        }
    }
    let f_max = model
        .loads
        .iter()
        .map(|l| l.force.norm())
        .fold(0.0, f64::max);
    for l in model.loads.iter().filter(|l| l.force.norm() > 0.0) {
        cv.arrow(
            l.point,
            l.force.normalize(),
            12.0 + 24.0 * l.force.norm() / f_max,
            "#c0392b",
        );
    }
    if model.gravity.norm() > 0.0 {
        let x = cv.width - cv.margin + 16.0;
        cv.arrow_px(x, cv.margin + 4.0, model.gravity.normalize(), 24.0, "#444");
        cv.text(x + 5.0, cv.margin + 16.0, 11.0, "g");
    }
    // The key names only the marks the picture holds.
    let pairs = model.interfaces.iter().filter(|i| i.b != GROUND).count();
    let key = [
        (pairs > 0, "blue: springs centroid–edge"),
        (model.interfaces.len() > pairs, "green: ground springs"),
        (!model.fixed.is_empty(), "black: clamped elements"),
        (f_max > 0.0, "red: loads"),
        (!model.ground.is_empty(), "hatched black: contact ground"),
    ];
    let key: Vec<&str> = key.iter().filter(|k| k.0).map(|k| k.1).collect();
    let caption = format!(
        "{}: {}, {}; {}",
        model.name,
        crate::output::count(model.elements.len(), "element", "elements"),
        crate::output::count(pairs, "interface", "interfaces"),
        key.join(", ")
    );
    cv.text(cv.margin, 20.0, 13.0, &caption);
    cv.finish()
}

/// The elements displaced by `u` (`ndof` per element, e.g. a mode shape), scaled so that the
/// largest vertex displacement is a tenth of the model's larger side, filled over the reference
/// outline (grey). `caption` is printed above with the scale factor.
pub fn displaced_svg(model: &Model, u: &[f64], caption: &str) -> String {
    let elements = element_polygons(model, displacement(model, u));
    let largest = super::largest_vertex_displacement(model, u);
    let (lo, hi) = extent(body_vertices(model));
    let scale = if largest > 0.0 {
        0.1 * (hi - lo).max() / largest
    } else {
        0.0
    };
    let polygons: Vec<(usize, Vec<Vec2>, Vec<Vec2>)> = elements
        .into_iter()
        .map(|(b, x, d)| {
            (
                b,
                x.clone(),
                x.iter().zip(&d).map(|(x, d)| x + d * scale).collect(),
            )
        })
        .collect();
    let mut cv = over_reference(&polygons, 0.6, &[]);
    cv.text(
        cv.margin,
        20.0,
        13.0,
        &format!("{caption} (displacements × {scale:.3e}; grey: reference)"),
    );
    cv.finish()
}

/// Broken interfaces: thick red lines.
pub const BROKEN: &str =
    r##"class="crack broken" stroke="#d62728" stroke-width="3.5" stroke-linecap="round""##;
/// Yielding interfaces: thinner orange lines.
pub const YIELDING: &str =
    r##"class="crack yielding" stroke="#ff8c00" stroke-width="1.5" stroke-linecap="round""##;

/// A run's final state (`rbsm draw --state`): the elements where `state` puts them, filled over
/// the reference outline (grey), and the cracks: each broken interface as a thick red line,
/// each yielding one as a thinner orange line, on its edge midway between its two sides. When
/// the largest vertex displacement is below a tenth of the model's larger side, the
/// displacements are magnified to a tenth (linear `N_e U_e`, like a mode shape) so that the
/// openings show; otherwise the elements are drawn where they are, with finite rotations. The
/// caption gives the time and the factor, the line below counts the interfaces of each state.
pub fn state_svg(model: &Model, state: &crate::output::FinalState) -> String {
    use crate::output::vtk::{interface_edge, Placement};
    let largest = element_polygons(model, displacement(model, &state.u))
        .iter()
        .flat_map(|p| p.2.iter())
        .map(|d| d.norm())
        .fold(0.0, f64::max);
    let (lo, hi) = extent(body_vertices(model));
    let size = (hi - lo).max();
    let (scale, placement) = if largest > 0.0 && largest < 0.1 * size {
        (0.1 * size / largest, Placement::Linear)
    } else {
        (1.0, Placement::Current)
    };
    let u: Vec<f64> = state.u.iter().map(|x| x * scale).collect();
    let nd = model.formulation.ndof();
    let polygons = element_polygons(model, |e, x| {
        placement.position(model, e, &u[e * nd..(e + 1) * nd], x)
    });
    let mut cv = over_reference(&polygons, 0.4, &model.ground);
    let of = |status| state.interfaces.iter().filter(move |i| i.status == status);
    // Broken ones (and those released to contact) last, over the yielding ones.
    for (status, style) in [
        (InterfaceStatus::Yielding, YIELDING),
        (InterfaceStatus::Broken, BROKEN),
        (InterfaceStatus::Released, BROKEN),
    ] {
        for i in of(status) {
            let [p1, p2] = interface_edge(model, &u, &model.interfaces[i.interface], placement);
            cv.line(p1, p2, style);
        }
    }
    let factor = if scale == 1.0 {
        "true scale".to_string()
    } else {
        format!("displacements × {scale:.3e}")
    };
    cv.text(
        cv.margin,
        20.0,
        13.0,
        &format!(
            "{} at t = {:.6e} s ({factor}; grey: reference)",
            model.name, state.t
        ),
    );
    let legend = if state.interfaces.is_empty() {
        "no interface can fail".to_string()
    } else {
        format!(
            "{} broken (thick red, {} of them released to contact), {} yielding (orange), {} \
             elastic",
            of(InterfaceStatus::Broken).count() + of(InterfaceStatus::Released).count(),
            of(InterfaceStatus::Released).count(),
            of(InterfaceStatus::Yielding).count(),
            of(InterfaceStatus::Elastic).count()
        )
    };
    cv.text(cv.margin, 38.0, 13.0, &legend);
    cv.finish()
}

/// Writes `mode_001.svg`, ... into `dir`: each mode shape drawn by [`displaced_svg`], captioned
/// with its frequency (Hz); `omega` are the circular frequencies (rad/s) of the `shapes`.
///
/// # Errors
/// `dir` cannot be created, or a `mode_NNN.svg` cannot be written in it.
pub fn write_mode_shapes(
    dir: &std::path::Path,
    model: &Model,
    omega: &[f64],
    shapes: &[Vec<f64>],
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for (k, (shape, omega)) in shapes.iter().zip(omega).enumerate() {
        let caption = format!(
            "{} mode {}: f = {:.6e} Hz",
            model.name,
            k + 1,
            omega / (2.0 * std::f64::consts::PI)
        );
        let path = dir.join(format!("mode_{:03}.svg", k + 1));
        crate::output::write_atomic(&path, displaced_svg(model, shape, &caption).as_bytes())?;
    }
    Ok(())
}

/// A canvas fitted to `polygons` (`(body, reference, placed)` per element) and the parts of
/// `ground` near them, with the reference outlines in grey, the ground hatched and the placed
/// elements over them, filled by body, outlined `stroke` wide.
fn over_reference(
    polygons: &[(usize, Vec<Vec2>, Vec<Vec2>)],
    stroke: f64,
    ground: &[[Vec2; 2]],
) -> Canvas {
    let points = || {
        polygons
            .iter()
            .flat_map(|p| p.1.iter().chain(&p.2).copied())
    };
    let ground = ground_near(ground, extent(points()));
    let mut cv = Canvas::fit(points().chain(ground.iter().flatten().copied()), 800.0);
    draw_ground(&mut cv, &ground);
    for (_, reference, _) in polygons {
        cv.polygon(
            reference,
            r##"fill="none" stroke="#bbb" stroke-width="0.6""##,
        );
    }
    for (b, _, placed) in polygons {
        let fill = BODY_FILLS[b % BODY_FILLS.len()];
        cv.polygon(
            placed,
            &format!(
                r##"fill="{fill}" fill-opacity="0.85" stroke="#333" stroke-width="{stroke}""##
            ),
        );
    }
    cv
}
