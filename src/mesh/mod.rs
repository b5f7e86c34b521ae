//! Meshes: vertices and counter-clockwise polygonal cells, with their edges found once.
//!
//! Pure geometry; the model (`crate::model`) turns cells into elements and shared edges into
//! interfaces. Generators: [`grid`] (rectangles or triangles), [`voronoi`] (centroidal Voronoi
//! cells clipped to a rectangle), [`Mesh::from_polygons`] (explicit cells from the scene) and
//! [`gmsh`] (MSH 4.1 files).

pub mod buckets;
pub mod geometry;
pub mod gmsh;
pub mod grid;
pub mod voronoi;

pub use gmsh::EdgeGroup;

use crate::error::{Error, Result};
use crate::input::scene::{EdgeSet, GmshSpec, GridSpec, MeshSpec, PolygonsSpec, Side, VoronoiSpec};
use crate::mesh::buckets::{BucketLists, Buckets};
use crate::mesh::geometry::{
    area_properties, point_in_polygon, segment_distance, segments_cross, Vec2,
};
use std::collections::HashMap;

/// An edge shared by two cells: `a` runs `v1 → v2` counter-clockwise, `b` runs it backwards.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SharedEdge {
    /// The cell that runs the edge `v1 → v2`.
    pub a: u32,
    /// The cell that runs it `v2 → v1`.
    pub b: u32,
    /// First vertex (counter-clockwise for `a`).
    pub v1: u32,
    /// Second vertex.
    pub v2: u32,
}

/// An edge of one cell only, with the bounding-box side it lies on (if any).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundaryEdge {
    /// The cell the edge belongs to.
    pub cell: u32,
    /// First vertex, counter-clockwise around the cell.
    pub v1: u32,
    /// Second vertex.
    pub v2: u32,
    /// The side of the bounding box it lies on, if any.
    pub side: Option<Side>,
}

/// A conforming polygonal mesh.
#[derive(Debug, Clone)]
pub struct Mesh {
    /// Vertex coordinates (m).
    pub vertices: Vec<Vec2>,
    /// `cell_start[c]..cell_start[c + 1]` indexes `cell_vertices` for cell `c`.
    pub cell_start: Vec<u32>,
    /// Vertex indices of all cells, counter-clockwise, concatenated.
    pub cell_vertices: Vec<u32>,
    /// Every edge shared by two cells, found once.
    pub shared: Vec<SharedEdge>,
    /// Every edge that belongs to one cell only.
    pub boundary: Vec<BoundaryEdge>,
    /// Named groups of boundary edges (gmsh physical groups; empty for generated meshes).
    pub groups: Vec<EdgeGroup>,
}

/// How much checking a cell list needs: generated meshes are valid by construction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Checks {
    /// Orientation, degeneracy and edge matching only.
    Generated,
    /// Also self-intersection, hanging vertices and cells lying inside others.
    UserInput,
}

/// Elements of a body's mesh as its scene entry gives them, before meshing; `None` for a gmsh
/// file, known only once read.
pub fn cells_of(mesh: &MeshSpec) -> Option<u64> {
    match mesh {
        MeshSpec::Grid(g) => Some(g.cells[0] as u64 * g.cells[1] as u64 * g.cell.per_cell() as u64),
        MeshSpec::Voronoi(v) => Some(v.sites as u64),
        MeshSpec::Polygons(p) => Some(p.cells.len() as u64),
        MeshSpec::Gmsh(_) => None,
    }
}

impl Mesh {
    /// The mesh a body's scene entry `spec` asks for (the one place that reads `mesh.kind`),
    /// `at` its place in the scene (`bodies[0].mesh`).
    ///
    /// # Errors
    /// As the generator the entry names: [`grid::grid`], [`voronoi::voronoi`],
    /// [`Mesh::from_polygons`] or [`gmsh::read`].
    pub fn from_spec(body: &str, at: &str, spec: &MeshSpec) -> Result<Mesh> {
        let v = |p: &[f64; 2]| Vec2::new(p[0], p[1]);
        match spec {
            MeshSpec::Grid(GridSpec {
                origin,
                size,
                cells,
                cell,
            }) => grid::grid(body, v(origin), v(size), cells[0], cells[1], *cell),
            MeshSpec::Voronoi(VoronoiSpec {
                origin,
                size,
                sites,
                seed,
                lloyd,
                domain,
            }) => {
                let outline: Option<Vec<Vec2>> = domain
                    .as_ref()
                    .map(|d| d.outline(*sites).iter().map(v).collect());
                voronoi::voronoi(
                    body,
                    v(origin),
                    v(size),
                    *sites,
                    *seed,
                    *lloyd,
                    outline.as_deref(),
                )
            }
            MeshSpec::Polygons(PolygonsSpec { vertices, cells }) => {
                Mesh::from_polygons(body, vertices.iter().map(v).collect(), cells)
            }
            MeshSpec::Gmsh(GmshSpec { path }) => crate::mesh::gmsh::read(body, at, path),
        }
    }

    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.cell_start.len() - 1
    }

    /// Vertex indices of cell `c`, counter-clockwise.
    pub fn cell(&self, c: usize) -> &[u32] {
        &self.cell_vertices[self.cell_start[c] as usize..self.cell_start[c + 1] as usize]
    }

    /// Coordinates of the vertices of cell `c`.
    pub fn cell_points(&self, c: usize) -> Vec<Vec2> {
        self.cell(c)
            .iter()
            .map(|&v| self.vertices[v as usize])
            .collect()
    }

    /// Lower-left and upper-right corners of the mesh's bounding box.
    pub fn bounding_box(&self) -> (Vec2, Vec2) {
        let mut lo = Vec2::repeat(f64::INFINITY);
        let mut hi = Vec2::repeat(f64::NEG_INFINITY);
        for v in &self.vertices {
            lo = lo.inf(v);
            hi = hi.sup(v);
        }
        (lo, hi)
    }

    /// The boundary edges in `set`, in boundary order; `Err` with the reason when there are none.
    ///
    /// # Errors
    /// `set` is a group the mesh does not have (the message lists those it has), or holds no
    /// boundary edge: no edge lies on that side of the bounding box, or none of the group's edges
    /// is on the boundary.
    pub fn edges_in(&self, set: &EdgeSet) -> std::result::Result<Vec<&BoundaryEdge>, String> {
        let edges: Vec<&BoundaryEdge> = match set {
            EdgeSet::Side(side) => self
                .boundary
                .iter()
                .filter(|e| e.side == Some(*side))
                .collect(),
            EdgeSet::Group(name) => {
                let Some(group) = self.groups.iter().find(|g| &g.name == name) else {
                    let known: Vec<&str> = self.groups.iter().map(|g| g.name.as_str()).collect();
                    return Err(format!(
                        "no side or edge group `{name}`: use left, right, bottom, top{}",
                        if known.is_empty() {
                            String::new()
                        } else {
                            format!(" or a group of the mesh: {}", known.join(", "))
                        }
                    ));
                };
                let mut pairs = group.edges.clone();
                pairs.sort_unstable();
                self.boundary
                    .iter()
                    .filter(|e| {
                        pairs
                            .binary_search(&[e.v1.min(e.v2), e.v1.max(e.v2)])
                            .is_ok()
                    })
                    .collect()
            }
        };
        if edges.is_empty() {
            return Err(match set {
                EdgeSet::Side(side) => {
                    format!("no boundary edge lies on side `{side:?}` of the body's bounding box")
                }
                EdgeSet::Group(name) => {
                    format!("edge group `{name}` holds no boundary edge of the mesh")
                }
            });
        }
        Ok(edges)
    }

    /// A mesh from explicit polygons, as given in a scene (`mesh.kind = "polygons"`).
    ///
    /// Cells must be counter-clockwise, non-degenerate, simple, non-overlapping and conforming
    /// (no vertex of one cell in the middle of another cell's edge); each error names the cell.
    ///
    /// # Errors
    /// There are no cells, a vertex index is out of range or a coordinate is not finite; a cell
    /// has fewer than 3 vertices, repeats one, has no area, is clockwise, crosses or touches
    /// itself; or cells overlap, lie inside one another, share an edge among more than two, or
    /// do not conform. The error names the cell.
    pub fn from_polygons(body: &str, vertices: Vec<Vec2>, cells: &[Vec<usize>]) -> Result<Self> {
        for (c, cell) in cells.iter().enumerate() {
            if let Some(&v) = cell.iter().find(|&&v| v >= vertices.len()) {
                return Err(Error::mesh(
                    body,
                    c,
                    format!("vertex index {v} is out of range (0..{})", vertices.len()),
                ));
            }
        }
        let cells: Vec<Vec<u32>> = cells
            .iter()
            .map(|c| c.iter().map(|&v| v as u32).collect())
            .collect();
        Mesh::build(body, vertices, &cells, Checks::UserInput)
    }

    /// Checks the cells, finds every edge once and tags boundary edges by side.
    pub(crate) fn build(
        body: &str,
        vertices: Vec<Vec2>,
        cells: &[Vec<u32>],
        checks: Checks,
    ) -> Result<Self> {
        if cells.is_empty() {
            return Err(Error::mesh(body, 0, "the mesh has no cells"));
        }
        if let Some(i) = vertices
            .iter()
            .position(|v| !v.x.is_finite() || !v.y.is_finite())
        {
            return Err(Error::scene(
                format!("mesh.vertices[{i}]"),
                "coordinates must be finite numbers",
            ));
        }
        let mut cell_start = Vec::with_capacity(cells.len() + 1);
        let mut cell_vertices = Vec::with_capacity(cells.iter().map(Vec::len).sum());
        cell_start.push(0u32);
        for (c, cell) in cells.iter().enumerate() {
            check_cell(body, c, cell, &vertices, checks)?;
            cell_vertices.extend_from_slice(cell);
            cell_start.push(cell_vertices.len() as u32);
        }
        let mut mesh = Mesh {
            vertices,
            cell_start,
            cell_vertices,
            shared: Vec::new(),
            boundary: Vec::new(),
            groups: Vec::new(),
        };
        mesh.match_edges(body)?;
        if checks == Checks::UserInput {
            mesh.check_conforming(body)?;
            mesh.check_no_nested_cells(body)?;
        }
        mesh.tag_sides();
        Ok(mesh)
    }

    /// Pairs the edges of all cells by their vertex indices (sort, then scan).
    fn match_edges(&mut self, body: &str) -> Result<()> {
        let mut keys: Vec<(u64, u32, u32, u32)> = Vec::with_capacity(self.cell_vertices.len());
        for c in 0..self.n_cells() {
            let cell = self.cell(c);
            for k in 0..cell.len() {
                let (v1, v2) = (cell[k], cell[(k + 1) % cell.len()]);
                let key = ((v1.min(v2) as u64) << 32) | v1.max(v2) as u64;
                keys.push((key, c as u32, v1, v2));
            }
        }
        keys.sort_unstable();
        let mut i = 0;
        while i < keys.len() {
            let mut j = i + 1;
            while j < keys.len() && keys[j].0 == keys[i].0 {
                j += 1;
            }
            let (_, a, v1, v2) = keys[i];
            match j - i {
                1 => self.boundary.push(BoundaryEdge {
                    cell: a,
                    v1,
                    v2,
                    side: None,
                }),
                2 => {
                    let (_, b, w1, _) = keys[i + 1];
                    if w1 == v1 {
                        return Err(Error::mesh(
                            body,
                            a.max(b) as usize,
                            format!(
                                "overlaps cell {}: both run their common edge ({v1}, {v2}) in the \
                                same direction",
                                a.min(b)
                            ),
                        ));
                    }
                    let (a, b, v1, v2) = if a < b {
                        (a, b, v1, v2)
                    } else {
                        (b, a, v2, v1)
                    };
                    self.shared.push(SharedEdge { a, b, v1, v2 });
                }
                _ => {
                    return Err(Error::mesh(
                        body,
                        keys[j - 1].1 as usize,
                        format!(
                        "edge ({v1}, {v2}) is used by {} cells; at most two cells may share an \
                            edge", j - i),
                    ));
                }
            }
            i = j;
        }
        // Element order, not key order, so that the interface list is easy to read.
        self.shared.sort_unstable_by_key(|e| (e.a, e.b));
        self.boundary.sort_unstable_by_key(|e| e.cell);
        Ok(())
    }

    /// No vertex may lie inside a boundary edge: that edge would be non-conforming.
    fn check_conforming(&self, body: &str) -> Result<()> {
        let (lo, hi) = self.bounding_box();
        let scale = (hi - lo).norm();
        let grid = Buckets::new(lo, hi, self.vertices.len());
        let mut vertex_buckets = BucketLists::default();
        vertex_buckets.fill(&grid, self.vertices.len(), |i| {
            (self.vertices[i], self.vertices[i])
        });
        for e in &self.boundary {
            let (p, q) = (self.vertices[e.v1 as usize], self.vertices[e.v2 as usize]);
            let d = q - p;
            let l2 = d.norm_squared();
            for b in grid.covering(p.inf(&q), p.sup(&q)) {
                for &i in vertex_buckets.bucket(b) {
                    if i == e.v1 || i == e.v2 {
                        continue;
                    }
                    let x = self.vertices[i as usize];
                    let s = (x - p).dot(&d) / l2;
                    let off = d.perp(&(x - p)).abs() / l2.sqrt();
                    if s > 1e-9 && s < 1.0 - 1e-9 && off <= 1e-10 * scale {
                        return Err(Error::mesh(
                            body,
                            e.cell as usize,
                            format!(
                            "non-conforming edge ({}, {}): vertex {i} lies on it; split the edge \
                                at that vertex", e.v1, e.v2),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// No cell may lie inside another one (overlap without a common edge).
    fn check_no_nested_cells(&self, body: &str) -> Result<()> {
        let (lo, hi) = self.bounding_box();
        let grid = Buckets::new(lo, hi, self.n_cells());
        let mut cell_buckets = BucketLists::default();
        cell_buckets.fill(&grid, self.n_cells(), |c| {
            let pts = self.cell_points(c);
            pts.iter()
                .fold((pts[0], pts[0]), |(a, b), p| (a.inf(p), b.sup(p)))
        });
        for d in 0..self.n_cells() {
            let centroid = area_properties(&self.cell_points(d)).centroid;
            for &c in cell_buckets.bucket(grid.index(centroid)) {
                if c as usize != d && point_in_polygon(centroid, &self.cell_points(c as usize)) {
                    return Err(Error::mesh(
                        body,
                        d,
                        format!("overlaps cell {c}: its centroid lies inside it"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Tags each boundary edge with the side of the bounding box it lies on.
    fn tag_sides(&mut self) {
        let (lo, hi) = self.bounding_box();
        let tol = 1e-9 * (hi - lo).norm();
        let on = |a: f64, b: f64, x: f64| (a - x).abs() <= tol && (b - x).abs() <= tol;
        for e in &mut self.boundary {
            let (p, q) = (self.vertices[e.v1 as usize], self.vertices[e.v2 as usize]);
            e.side = if on(p.x, q.x, lo.x) {
                Some(Side::Left)
            } else if on(p.x, q.x, hi.x) {
                Some(Side::Right)
            } else if on(p.y, q.y, lo.y) {
                Some(Side::Bottom)
            } else if on(p.y, q.y, hi.y) {
                Some(Side::Top)
            } else {
                None
            };
        }
    }
}

/// Checks one cell: enough distinct vertices, positive area (counter-clockwise), and for user
/// input no self-intersection.
fn check_cell(body: &str, c: usize, cell: &[u32], vertices: &[Vec2], checks: Checks) -> Result<()> {
    if cell.len() < 3 {
        return Err(Error::mesh(
            body,
            c,
            format!("has {} vertices; a cell needs at least 3", cell.len()),
        ));
    }
    let pts: Vec<Vec2> = cell.iter().map(|&v| vertices[v as usize]).collect();
    let mut seen = HashMap::with_capacity(cell.len());
    for (k, &v) in cell.iter().enumerate() {
        if let Some(first) = seen.insert(v, k) {
            return Err(Error::mesh(
                body,
                c,
                format!("is degenerate: vertex {v} appears twice (positions {first} and {k})"),
            ));
        }
    }
    let perimeter: f64 = (0..pts.len())
        .map(|k| (pts[(k + 1) % pts.len()] - pts[k]).norm())
        .sum();
    let area = area_properties(&pts).area;
    if area.abs() <= 1e-12 * perimeter * perimeter {
        return Err(Error::mesh(
            body,
            c,
            format!("is degenerate: its area {area:e} m² is zero"),
        ));
    }
    if area < 0.0 {
        return Err(Error::mesh(
            body,
            c,
            "is clockwise; list its vertices counter-clockwise",
        ));
    }
    if checks == Checks::UserInput {
        let n = pts.len();
        for i in 0..n {
            for j in i + 2..n {
                if i == 0 && j == n - 1 {
                    continue;
                }
                let (p, q) = ((pts[i], pts[(i + 1) % n]), (pts[j], pts[(j + 1) % n]));
                if segments_cross(p.0, p.1, q.0, q.1) {
                    return Err(Error::mesh(
                        body,
                        c,
                        format!("is self-intersecting: edges {i} and {j} cross"),
                    ));
                }
                let gap = segment_distance(p.0, p.1, q.0, q.1);
                if gap <= 1e-9 * perimeter {
                    return Err(Error::mesh(
                        body,
                        c,
                        format!(
                            "touches itself: edges {i} and {j} \
                        meet ({gap:e} m apart), as in a figure 8; split it into two cells"
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x: f64, y: f64) -> Vec<Vec2> {
        vec![
            Vec2::new(x, y),
            Vec2::new(x + 1.0, y),
            Vec2::new(x + 1.0, y + 1.0),
            Vec2::new(x, y + 1.0),
        ]
    }

    #[test]
    fn two_squares_share_one_edge() {
        let mut v = square(0.0, 0.0);
        v.extend([Vec2::new(2.0, 0.0), Vec2::new(2.0, 1.0)]);
        let m = Mesh::from_polygons("b", v, &[vec![0, 1, 2, 3], vec![1, 4, 5, 2]]).unwrap();
        assert_eq!(
            m.shared,
            vec![SharedEdge {
                a: 0,
                b: 1,
                v1: 1,
                v2: 2
            }]
        );
        assert_eq!(m.boundary.len(), 6);
        assert_eq!(
            m.boundary
                .iter()
                .filter(|e| e.side == Some(Side::Left))
                .count(),
            1
        );
        assert_eq!(
            m.boundary
                .iter()
                .filter(|e| e.side == Some(Side::Bottom))
                .count(),
            2
        );
    }

    #[test]
    fn clockwise_cell_is_named() {
        let err = Mesh::from_polygons("b", square(0.0, 0.0), &[vec![0, 3, 2, 1]])
            .unwrap_err()
            .to_string();
        assert!(err.contains("cell 0") && err.contains("clockwise"), "{err}");
    }

    #[test]
    fn hanging_vertex_is_non_conforming() {
        // Cell 0 is 2 x 1; cells 1 and 2 sit on top of it, meeting at (1, 1).
        let v = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(2.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(0.0, 2.0),
            Vec2::new(1.0, 2.0),
            Vec2::new(2.0, 2.0),
        ];
        let err = Mesh::from_polygons(
            "b",
            v,
            &[vec![0, 1, 2, 4], vec![4, 3, 6, 5], vec![3, 2, 7, 6]],
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("non-conforming") && err.contains("vertex 3"),
            "{err}"
        );
    }

    #[test]
    fn nested_and_same_direction_cells_overlap() {
        let mut v = square(0.0, 0.0);
        v.extend([
            Vec2::new(0.25, 0.25),
            Vec2::new(0.5, 0.25),
            Vec2::new(0.5, 0.5),
        ]);
        let err = Mesh::from_polygons("b", v.clone(), &[vec![0, 1, 2, 3], vec![4, 5, 6]])
            .unwrap_err()
            .to_string();
        assert!(err.contains("overlaps"), "{err}");
        let err = Mesh::from_polygons("b", square(0.0, 0.0), &[vec![0, 1, 2, 3], vec![0, 1, 2]])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("overlaps") || err.contains("same direction"),
            "{err}"
        );
    }

    #[test]
    fn degenerate_and_self_intersecting_cells_are_errors() {
        let v = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(2.0, 0.0),
        ];
        let err = Mesh::from_polygons("b", v, &[vec![0, 1, 2]])
            .unwrap_err()
            .to_string();
        assert!(err.contains("degenerate"), "{err}");
        let v = vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
        ];
        let err = Mesh::from_polygons("b", v, &[vec![0, 1, 2, 3]])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("self-intersecting") || err.contains("degenerate"),
            "{err}"
        );
        // A figure 8: two triangles that meet at (1, 1), listed as one cell.
        let v = [
            (0.0, 0.0),
            (2.0, 0.0),
            (1.0, 1.0),
            (2.0, 2.0),
            (0.0, 2.0),
            (1.0, 1.0),
        ]
        .map(|(x, y)| Vec2::new(x, y))
        .to_vec();
        let err = Mesh::from_polygons("b", v, &[vec![0, 1, 2, 3, 4, 5]])
            .unwrap_err()
            .to_string();
        assert!(err.contains("touches itself: edges 1 and 4"), "{err}");
    }
}
