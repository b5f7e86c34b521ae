//! Centroidal Voronoi cells clipped to a rectangle, or to a polygon inside it (a notched beam, a
//! disk cut as a regular polygon): seeded random sites, then Lloyd iterations that move each
//! site to the area centroid of its cell. The Voronoi step itself is the `voronoice` crate
//! (Delaunay by `delaunator`, dual cells clipped to the box); a domain then clips each convex
//! cell (Sutherland–Hodgman, the domain clipped by the cell's half-planes).

use super::{Checks, Mesh};
use crate::error::{Error, Result};
use crate::mesh::geometry::{
    area_properties, cross3, point_in_polygon, segment_distance, segments_cross, Vec2,
};
use rand::{Rng, SeedableRng};
use rustc_hash::FxHashMap;
use voronoice::{BoundingBox, Point, VoronoiBuilder};

/// How many random points of the rectangle are drawn per site at most: ten times what a domain
/// covering 1/1000 of it (the least the scene allows) needs on average.
const DRAWS_PER_SITE: usize = 10_000;

/// `sites` cells in the rectangle `origin .. origin + size`, or in the polygon `domain` inside
/// it, after `lloyd` centroid iterations; the same `seed` gives the same mesh on every machine
/// (ChaCha8 generator). With a domain, the sites are the first `sites` random points of the
/// rectangle that lie inside it, and a Lloyd iteration leaves a site where it is when the
/// centroid of its cell falls outside the domain (a non-convex cell at a re-entrant corner).
///
/// # Errors
/// The diagram of the sites cannot be built, loses sites, or has a cell that is degenerate or has
/// no area (too few or coincident sites, or sites nearly on one line in an extreme rectangle); a
/// domain that covers too little of the rectangle, or cuts a cell in two (a feature narrower
/// than a cell); or the welded cells do not form a valid mesh.
pub fn voronoi(
    body: &str,
    origin: Vec2,
    size: Vec2,
    sites: usize,
    seed: u64,
    lloyd: usize,
    domain: Option<&[Vec2]>,
) -> Result<Mesh> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut draw =
        || origin + Vec2::new(rng.random::<f64>() * size.x, rng.random::<f64>() * size.y);
    let mut pts: Vec<Vec2> = match domain {
        None => (0..sites).map(|_| draw()).collect(),
        Some(domain) => {
            let pts: Vec<Vec2> = std::iter::repeat_with(draw)
                .take(DRAWS_PER_SITE * sites)
                .filter(|p| point_in_polygon(*p, domain))
                .take(sites)
                .collect();
            if pts.len() < sites {
                return Err(Error::mesh(
                    body,
                    0,
                    "too few random points of the rectangle `origin`, `size` fell inside the \
                     domain: fit the rectangle to it",
                ));
            }
            pts
        }
    };
    // Cells numbered strip by strip, as in a grid: neighbours get nearby numbers, so the
    // evaluators walk memory forwards instead of at random (10× faster at 10⁵ cells). The
    // sites are numbered so before the Lloyd iterations too, which then also walk nearby
    // coordinates (a 10⁶-cell mesh builds in 10 % less time), and again after them.
    let strips = ((sites as f64 * size.y / size.x).sqrt().round() as usize).max(1);
    let strip = |p: &Vec2| (((p.y - origin.y) / size.y * strips as f64) as usize).min(strips - 1);
    pts.sort_by(|p, q| strip(p).cmp(&strip(q)).then(p.x.total_cmp(&q.x)));
    for _ in 0..lloyd {
        pts = clipped_cells(body, origin, size, &pts, domain, false)?
            .iter()
            .enumerate()
            .map(|(c, points)| {
                let cell = area_properties(points);
                match cell.area != 0.0 && cell.centroid.iter().all(|x| x.is_finite()) {
                    true if domain.is_some_and(|d| !point_in_polygon(cell.centroid, d)) => {
                        Ok(pts[c])
                    }
                    true => Ok(cell.centroid),
                    false => Err(Error::mesh(
                        body,
                        c,
                        "the Voronoi cell has no area, so no centroid for a Lloyd iteration \
                         (coincident sites, or an extreme rectangle)",
                    )),
                }
            })
            .collect::<Result<_>>()?;
    }
    pts.sort_by(|p, q| strip(p).cmp(&strip(q)).then(p.x.total_cmp(&q.x)));
    weld(
        body,
        origin,
        size,
        &clipped_cells(body, origin, size, &pts, domain, true)?,
    )
}

/// Cells as coordinate lists, one after the other: one allocation for a million cells, not a
/// million.
struct Cells {
    points: Vec<Vec2>,
    /// Where each cell's points end in `points`.
    ends: Vec<usize>,
}

impl Cells {
    fn iter(&self) -> impl Iterator<Item = &[Vec2]> {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts.zip(&self.ends).map(|(a, &b)| &self.points[a..b])
    }
}

/// The Voronoi cells of `sites`, clipped to the rectangle and to the domain, as coordinate
/// lists. A cell the domain cuts in two is refused in the `last` diagram, the mesh's; before,
/// in a Lloyd iteration, its two parts joined by their bridge give the centroid of both.
fn clipped_cells(
    body: &str,
    origin: Vec2,
    size: Vec2,
    sites: &[Vec2],
    domain: Option<&[Vec2]>,
    last: bool,
) -> Result<Cells> {
    let centre = origin + 0.5 * size;
    let diagram = VoronoiBuilder::default()
        .set_sites(sites.iter().map(|p| Point { x: p.x, y: p.y }).collect())
        .set_bounding_box(BoundingBox::new(
            Point {
                x: centre.x,
                y: centre.y,
            },
            size.x,
            size.y,
        ))
        .build()
        .ok_or_else(|| {
            Error::mesh(
                body,
                0,
                "the Voronoi diagram could not be built (too few or coincident sites)",
            )
        })?;
    if diagram.sites().len() != sites.len() {
        return Err(Error::mesh(
            body,
            0,
            "some Voronoi sites are missing from the diagram (sites outside the rectangle, \
             coincident, or nearly on one line in an extreme rectangle)",
        ));
    }
    let v = diagram.vertices();
    let mut cells = Cells {
        points: Vec::with_capacity(7 * sites.len()),
        ends: Vec::with_capacity(sites.len()),
    };
    let (mut cell, mut piece, mut spare) = (Vec::new(), Vec::new(), Vec::new());
    for (k, c) in diagram.cells().iter().enumerate() {
        cell.clear();
        cell.extend(c.iter().map(|&i| Vec2::new(v[i].x, v[i].y)));
        match domain {
            Some(domain) if !cell.iter().all(|p| point_in_polygon(*p, domain)) => {
                clip(domain, &cell, &mut piece, &mut spare);
                tidy(&mut piece, 1e-9 * size.norm());
                if last && cut_in_two(&piece, 1e-9 * size.norm()) {
                    return Err(Error::mesh(
                        body,
                        k,
                        "the domain cuts this Voronoi cell in two (a notch or a neck narrower \
                         than a cell): use more sites",
                    ));
                }
                cells.points.extend_from_slice(&piece);
            }
            _ => cells.points.extend_from_slice(&cell),
        }
        cells.ends.push(cells.points.len());
    }
    let degenerate = cells.iter().position(|c| c.len() < 3);
    match degenerate {
        Some(c) => Err(Error::mesh(
            body,
            c,
            "the Voronoi cell is degenerate (coincident sites, or an extreme rectangle)",
        )),
        None => Ok(cells),
    }
}

/// Whether a domain's `outline` fits a Voronoi mesh in the rectangle `origin`, `size`: inside
/// it (to 1e-9 of its size), not crossing itself, and covering at least 1/1000 of it (the sites
/// are drawn in the rectangle); the reason when it does not.
///
/// # Errors
/// What is wrong, for the caller to name the key.
pub fn check_domain(outline: &[Vec2], origin: Vec2, size: Vec2) -> std::result::Result<(), String> {
    let tol = 1e-9 * size.norm();
    let (lo, hi) = (
        origin - Vec2::repeat(tol),
        origin + size + Vec2::repeat(tol),
    );
    if let Some(i) = outline
        .iter()
        .position(|p| p.x < lo.x || p.y < lo.y || p.x > hi.x || p.y > hi.y)
    {
        return Err(format!(
            "the domain reaches outside the rectangle `origin`, `size` (at corner {i}): the \
             cells fill the part of the domain inside it"
        ));
    }
    let crossing = apart_edges(outline).any(|([a, b], [c, d])| segments_cross(a, b, c, d));
    let area = area_properties(outline).area.abs();
    if crossing || area <= tol * tol {
        return Err("the domain's outline crosses itself or encloses no area".into());
    }
    if area < 1e-3 * size.x * size.y {
        return Err(
            "the domain covers less than 1/1000 of the rectangle `origin`, `size`, \
                    where the sites are drawn: fit the rectangle to it"
                .into(),
        );
    }
    Ok(())
}

/// `subject ∩ cell` into `out` for a convex `cell` (either orientation), by Sutherland–Hodgman:
/// the subject clipped by each of the cell's half-planes in turn; `spare` is scratch. Where the
/// intersection has two parts, they come out joined by edges that run along a side of the cell
/// and back ([`cut_in_two`]).
fn clip(subject: &[Vec2], cell: &[Vec2], out: &mut Vec<Vec2>, spare: &mut Vec<Vec2>) {
    let orient = area_properties(cell).area.signum();
    out.clear();
    out.extend_from_slice(subject);
    for (i, &a) in cell.iter().enumerate() {
        let b = cell[(i + 1) % cell.len()];
        let side = |p: Vec2| orient * cross3(a, b, p);
        spare.clear();
        for (j, &p) in out.iter().enumerate() {
            let q = out[(j + 1) % out.len()];
            let (dp, dq) = (side(p), side(q));
            if dp >= 0.0 {
                spare.push(p);
            }
            if dp * dq < 0.0 {
                spare.push(p + (q - p) * (dp / (dp - dq)));
            }
        }
        std::mem::swap(out, spare);
        if out.is_empty() {
            return;
        }
    }
}

/// Every pair of a polygon's edges that do not follow each other, as their end points.
fn apart_edges(p: &[Vec2]) -> impl Iterator<Item = ([Vec2; 2], [Vec2; 2])> + '_ {
    let n = p.len();
    let edge = move |i: usize| [p[i], p[(i + 1) % n]];
    (0..n).flat_map(move |i| {
        (i + 2..n)
            .filter(move |&j| (j + 1) % n != i)
            .map(move |j| (edge(i), edge(j)))
    })
}

/// Takes out of a clipped cell what Sutherland–Hodgman leaves where the domain leaves and
/// re-enters the cell across one of its sides: repeated points (within `tol`) and spikes, a
/// point where the outline turns back along itself.
fn tidy(piece: &mut Vec<Vec2>, tol: f64) {
    loop {
        piece.dedup_by(|b, a| (*b - *a).norm() <= tol);
        while piece.len() > 1 && (piece[0] - piece[piece.len() - 1]).norm() <= tol {
            piece.pop();
        }
        let n = piece.len();
        let spike = (0..n).find(|&i| {
            let (a, b, c) = (piece[(i + n - 1) % n], piece[i], piece[(i + 1) % n]);
            (b - a).dot(&(c - b)) < 0.0 && cross3(a, b, c).abs() <= tol * (b - a).norm()
        });
        match spike {
            Some(i) if n > 3 => {
                piece.remove(i);
            }
            _ => return,
        }
    }
}

/// Whether a tidied clipped cell is two parts joined by a bridge: two of its edges that do not
/// follow each other come within `tol`.
fn cut_in_two(p: &[Vec2], tol: f64) -> bool {
    p.len() < 3 || apart_edges(p).any(|([a, b], [c, d])| segment_distance(a, b, c, d) <= tol)
}

/// `x` moved onto the side `lo` or `lo + len` of the rectangle when it lies within `tol` of it
/// but off it by more than round-off. A Voronoi vertex that near a side would otherwise be
/// welded to the clipped points there and pull the side in: `tests/properties.rs` found one
/// 5.6e-6 m inside a 4.3 × 6.8 m rectangle, and the cells lost 5.7e-6 m² of its area. Points
/// on a side to round-off stay as they are.
fn onto_side(x: f64, lo: f64, len: f64, tol: f64) -> f64 {
    let near = |side: f64| (1e-6 * tol..=tol).contains(&(x - side).abs());
    match (near(lo), near(lo + len)) {
        (true, _) => lo,
        (_, true) => lo + len,
        _ => x,
    }
}

/// Merges coincident vertices (within 1e-6 of the rectangle's size) so that neighbouring cells
/// share vertex indices, drops the zero-length edges that merging leaves, and orients every
/// cell counter-clockwise. voronoice clips each cell on its own, and where a Voronoi vertex
/// lies far outside the rectangle (nearly collinear sites in a thin strip) the two copies of a
/// clipped point differ by up to 5e-8 of a 8.4 m strip (`tests/properties.rs` found it): 1e-10
/// left such neighbours unjoined, with no interface between them.
fn weld(body: &str, origin: Vec2, size: Vec2, cells: &Cells) -> Result<Mesh> {
    let tol = 1e-6 * size.norm();
    let key = |p: Vec2| {
        (
            ((p.x - origin.x) / tol).round() as i64,
            ((p.y - origin.y) / tol).round() as i64,
        )
    };
    // Integer keys of a generated mesh: the fast hash of rustc's own tables (the build's hashing
    // took 8 % of a 10⁶-cell mesh with the standard one).
    let mut index: FxHashMap<(i64, i64), u32> = FxHashMap::default();
    let mut vertices: Vec<Vec2> = Vec::new();
    let mut out = Vec::with_capacity(cells.ends.len());
    for cell in cells.iter() {
        let mut ids: Vec<u32> = Vec::with_capacity(cell.len());
        for &p in cell {
            let p = Vec2::new(
                onto_side(p.x, origin.x, size.x, tol),
                onto_side(p.y, origin.y, size.y, tol),
            );
            let (kx, ky) = key(p);
            // A point near a rounding boundary may have its twin in a neighbouring bucket;
            // most twins are in their own. A bucket's vertex is the twin only if it is near.
            const BUCKETS: [(i64, i64); 9] = [
                (0, 0),
                (-1, -1),
                (-1, 0),
                (-1, 1),
                (0, -1),
                (0, 1),
                (1, -1),
                (1, 0),
                (1, 1),
            ];
            let found = BUCKETS.into_iter().find_map(|(dx, dy)| {
                let i = *index.get(&(kx + dx, ky + dy))?;
                ((vertices[i as usize] - p).norm() <= tol).then_some(i)
            });
            let id = found.unwrap_or_else(|| {
                vertices.push(p);
                index.insert((kx, ky), vertices.len() as u32 - 1);
                vertices.len() as u32 - 1
            });
            if ids.last() != Some(&id) {
                ids.push(id);
            }
        }
        if ids.len() > 1 && ids.first() == ids.last() {
            ids.pop();
        }
        // voronoice lists cell vertices clockwise; elements are counter-clockwise.
        if area_properties(cell).area < 0.0 {
            ids.reverse();
        }
        out.push(ids);
    }
    Mesh::build(body, vertices, &out, Checks::Generated)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cell_without_area_stops_the_lloyd_iterations() {
        // 400 cells in a 1 × 2.5e-7 m strip: the cells of the random sites are refused later
        // (welded to two vertices), but a Lloyd iteration before that met cells of no area,
        // whose centroids were NaN. A debug build of `voronoice` panicked on those sites
        // (`tests/fuzz.rs` found it); a release build left them out of the diagram, and the
        // error blamed sites outside the rectangle.
        let (o, s) = (Vec2::new(0.0, 0.0), Vec2::new(1.0, 2.5e-7));
        let random = voronoi("b", o, s, 400, 42, 0, None)
            .unwrap_err()
            .to_string();
        assert!(random.contains("at least 3"), "{random}");
        let e = voronoi("b", o, s, 400, 42, 1, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("has no area"), "{e}");
    }

    #[test]
    fn cells_tile_the_rectangle() {
        let (o, s) = (Vec2::new(1.0, 2.0), Vec2::new(2.0, 1.0));
        let m = voronoi("b", o, s, 60, 7, 5, None).unwrap();
        assert_eq!(m.n_cells(), 60);
        let total: f64 = (0..60)
            .map(|c| area_properties(&m.cell_points(c)).area)
            .sum();
        assert!((total - 2.0).abs() < 1e-12, "{total}");
        // Every boundary edge lies on the rectangle: the cells conform inside.
        assert!(m.boundary.iter().all(|e| e.side.is_some()));
        // Euler's formula for a planar subdivision: V - E + F = 1.
        let e = m.shared.len() + m.boundary.len();
        assert_eq!(m.vertices.len() as i64 - e as i64 + 60, 1);
    }

    #[test]
    fn same_seed_same_mesh() {
        let a = voronoi("b", Vec2::zeros(), Vec2::new(1.0, 1.0), 30, 3, 2, None).unwrap();
        let b = voronoi("b", Vec2::zeros(), Vec2::new(1.0, 1.0), 30, 3, 2, None).unwrap();
        assert_eq!(a.vertices, b.vertices);
    }

    /// A notched beam (a re-entrant notch from the bottom) and a disk (a regular 200-gon):
    /// the cells tile the domain to round-off, every boundary edge lies on the domain's
    /// outline, and the mesh is one piece (Euler's formula).
    #[test]
    fn cells_tile_a_notched_beam_and_a_disk() {
        let notched = [
            Vec2::new(0.0, 0.0),
            Vec2::new(0.48, 0.0),
            Vec2::new(0.48, 0.05),
            Vec2::new(0.52, 0.05),
            Vec2::new(0.52, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 0.2),
            Vec2::new(0.0, 0.2),
        ];
        let disk: Vec<Vec2> = (0..200)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 200.0;
                Vec2::new(0.5 + 0.5 * t.cos(), 0.5 + 0.5 * t.sin())
            })
            .collect();
        for (domain, origin, size, sites) in [
            (&notched[..], Vec2::zeros(), Vec2::new(1.0, 0.2), 800),
            (&disk[..], Vec2::zeros(), Vec2::new(1.0, 1.0), 500),
        ] {
            let m = voronoi("b", origin, size, sites, 1, 10, Some(domain)).unwrap();
            assert_eq!(m.n_cells(), sites);
            let total: f64 = (0..sites)
                .map(|c| area_properties(&m.cell_points(c)).area)
                .sum();
            let area = area_properties(domain).area;
            assert!((total - area).abs() < 1e-12 * area, "{total} ≠ {area}");
            let on_outline = |p: Vec2| {
                (0..domain.len()).any(|i| {
                    let (a, b) = (domain[i], domain[(i + 1) % domain.len()]);
                    crate::mesh::geometry::point_segment_distance(p, a, b) < 1e-9
                })
            };
            for e in &m.boundary {
                let (a, b) = (m.vertices[e.v1 as usize], m.vertices[e.v2 as usize]);
                assert!(on_outline(a) && on_outline(b) && on_outline(0.5 * (a + b)));
            }
            let e = m.shared.len() + m.boundary.len();
            assert_eq!(m.vertices.len() as i64 - e as i64 + sites as i64, 1);
        }
        // A slit far narrower than the cells, nearly through a square, cuts some in two, and
        // says so.
        let slit = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.501, 1.0),
            Vec2::new(0.501, 0.05),
            Vec2::new(0.499, 0.05),
            Vec2::new(0.499, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        let e = voronoi(
            "b",
            Vec2::zeros(),
            Vec2::new(1.0, 1.0),
            40,
            1,
            0,
            Some(&slit),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("cuts this Voronoi cell in two"), "{e}");
    }
}
