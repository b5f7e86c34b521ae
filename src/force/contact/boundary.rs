//! The bodies' boundaries and the ground segments in the reference configuration, as vertices
//! and edges: what point contact steps over, and what both contact models take their skins,
//! their extent (`rbsm check`) and the stiffness estimate from.

use super::{frame, NONE};
use crate::mesh::geometry::Vec2;
use crate::model::{Model, GROUND};

/// A vertex of an element on its body's boundary: a point that can enter another body.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub(super) struct Vertex {
    pub element: u32,
    pub body: u32,
    /// Offset from the element's centroid in the reference configuration (m).
    pub offset: Vec2,
    /// The element's boundary edges that meet here ([`NONE`] if only one does).
    pub edges: [u32; 2],
}

/// A surface that vertices can enter: a boundary edge of an element (counter-clockwise, solid
/// on its left) or a ground segment.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub(super) struct Edge {
    /// The element it belongs to, or [`GROUND`].
    pub element: u32,
    pub body: u32,
    /// End points, as indices into the points (vertices first, then ground points).
    pub ends: [u32; 2],
    /// Compliances `h / E_n` and `h / E_s` of this side (eq. 12 is `k = E / (h_a + h_b)`);
    /// zero for the ground.
    pub compliance: [f64; 2],
    /// Reference length (m).
    pub length: f64,
}

/// Every boundary edge of every body (in the order of each mesh's boundary) with its two
/// vertices, then the ground segments.
#[derive(Debug, Clone)]
pub(super) struct Boundary {
    pub vertices: Vec<Vertex>,
    pub edges: Vec<Edge>,
    /// The reference positions of the vertices, then the ground segments' end points.
    pub points: Vec<Vec2>,
}

impl Boundary {
    /// The boundary of `model`'s bodies and its ground segments.
    pub fn of(model: &Model) -> Boundary {
        let mut vertices = Vec::new();
        let mut edges = Vec::new();
        for (bi, body) in model.bodies.iter().enumerate() {
            let mesh = &body.mesh;
            let moduli = body.moduli;
            // The element's boundary vertices, numbered in order of first appearance.
            let mut index = std::collections::HashMap::new();
            for e in &mesh.boundary {
                let element = body.first_element + e.cell as usize;
                let centroid = model.elements[element].props.centroid;
                let (p1, p2) = (mesh.vertices[e.v1 as usize], mesh.vertices[e.v2 as usize]);
                let (_, n, length) = frame(p1, p2);
                let h = (p1 - centroid).dot(&n).abs();
                let id = edges.len() as u32;
                let mut end = |v: u32, p: Vec2| {
                    *index.entry((element, v)).or_insert_with(|| {
                        vertices.push(Vertex {
                            element: element as u32,
                            body: bi as u32,
                            offset: p - centroid,
                            edges: [NONE; 2],
                        });
                        vertices.len() as u32 - 1
                    })
                };
                let ends = [end(e.v1, p1), end(e.v2, p2)];
                for &v in &ends {
                    let slot = &mut vertices[v as usize].edges;
                    let k = if slot[0] == NONE { 0 } else { 1 };
                    slot[k] = id;
                }
                edges.push(Edge {
                    element: element as u32,
                    body: bi as u32,
                    ends,
                    compliance: [h / moduli[0], h / moduli[1]],
                    length,
                });
            }
        }
        let mut points: Vec<Vec2> = vertices
            .iter()
            .map(|v| model.elements[v.element as usize].props.centroid + v.offset)
            .collect();
        for g in &model.ground {
            // Stored `to → from`: the solid side is then on the left, as for a body's boundary.
            let at = points.len() as u32;
            points.extend([g[1], g[0]]);
            edges.push(Edge {
                element: GROUND,
                body: NONE,
                ends: [at, at + 1],
                compliance: [0.0; 2],
                length: (g[1] - g[0]).norm(),
            });
        }
        Boundary {
            vertices,
            edges,
            points,
        }
    }

    /// The skins of the two neighbour lists (m): a tenth of the mean boundary edge
    /// (edge-to-edge), and that or a twentieth of the longest boundary edge, whichever is
    /// larger (point: it also holds the depth within which a vertex placed inside an edge
    /// touches it).
    pub fn skins(&self) -> (f64, f64) {
        let body_edges = self.edges.iter().filter(|e| e.element != GROUND);
        let (total, longest) = body_edges
            .clone()
            .fold((0.0, 0.0f64), |(t, l), e| (t + e.length, l.max(e.length)));
        let tenth = 0.1 * total / body_edges.count().max(1) as f64;
        (tenth, tenth.max(0.05 * longest))
    }
}
