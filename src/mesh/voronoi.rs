//! Centroidal Voronoi cells clipped to a rectangle: seeded random sites, then Lloyd iterations
//! that move each site to the area centroid of its cell. The Voronoi step itself is the
//! `voronoice` crate (Delaunay by `delaunator`, dual cells clipped to the box).

use super::{Checks, Mesh};
use crate::error::{Error, Result};
use crate::mesh::geometry::{area_properties, Vec2};
use rand::{Rng, SeedableRng};
use rustc_hash::FxHashMap;
use voronoice::{BoundingBox, Point, VoronoiBuilder};

/// `sites` cells in the rectangle `origin .. origin + size`, after `lloyd` centroid iterations;
/// the same `seed` gives the same mesh on every machine (ChaCha8 generator).
///
/// # Errors
/// The diagram of the sites cannot be built, loses sites, or has a cell that is degenerate or has
/// no area (too few or coincident sites, or sites nearly on one line in an extreme rectangle); or
/// the welded cells do not form a valid mesh.
pub fn voronoi(
    body: &str,
    origin: Vec2,
    size: Vec2,
    sites: usize,
    seed: u64,
    lloyd: usize,
) -> Result<Mesh> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut pts: Vec<Vec2> = (0..sites)
        .map(|_| origin + Vec2::new(rng.random::<f64>() * size.x, rng.random::<f64>() * size.y))
        .collect();
    // Cells numbered strip by strip, as in a grid: neighbours get nearby numbers, so the
    // evaluators walk memory forwards instead of at random (10× faster at 10⁵ cells). The
    // sites are numbered so before the Lloyd iterations too, which then also walk nearby
    // coordinates (a 10⁶-cell mesh builds in 10 % less time), and again after them.
    let strips = ((sites as f64 * size.y / size.x).sqrt().round() as usize).max(1);
    let strip = |p: &Vec2| (((p.y - origin.y) / size.y * strips as f64) as usize).min(strips - 1);
    pts.sort_by(|p, q| strip(p).cmp(&strip(q)).then(p.x.total_cmp(&q.x)));
    for _ in 0..lloyd {
        pts = clipped_cells(body, origin, size, &pts)?
            .iter()
            .enumerate()
            .map(|(c, points)| {
                let cell = area_properties(points);
                match cell.area != 0.0 && cell.centroid.iter().all(|x| x.is_finite()) {
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
        &clipped_cells(body, origin, size, &pts)?,
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

/// The Voronoi cells of `sites`, clipped to the rectangle, as coordinate lists.
fn clipped_cells(body: &str, origin: Vec2, size: Vec2, sites: &[Vec2]) -> Result<Cells> {
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
    for c in diagram.cells() {
        cells
            .points
            .extend(c.iter().map(|&i| Vec2::new(v[i].x, v[i].y)));
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
        let random = voronoi("b", o, s, 400, 42, 0).unwrap_err().to_string();
        assert!(random.contains("at least 3"), "{random}");
        let e = voronoi("b", o, s, 400, 42, 1).unwrap_err().to_string();
        assert!(e.contains("has no area"), "{e}");
    }

    #[test]
    fn cells_tile_the_rectangle() {
        let (o, s) = (Vec2::new(1.0, 2.0), Vec2::new(2.0, 1.0));
        let m = voronoi("b", o, s, 60, 7, 5).unwrap();
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
        let a = voronoi("b", Vec2::zeros(), Vec2::new(1.0, 1.0), 30, 3, 2).unwrap();
        let b = voronoi("b", Vec2::zeros(), Vec2::new(1.0, 1.0), 30, 3, 2).unwrap();
        assert_eq!(a.vertices, b.vertices);
    }
}
