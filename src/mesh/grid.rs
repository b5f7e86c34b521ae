//! Structured grids of rectangles, of triangles cut along the lower-left to upper-right
//! diagonal, or of four triangles per rectangle cut by both diagonals.

use super::{Checks, Mesh};
use crate::error::Result;
use crate::input::scene::Cell;
use crate::mesh::geometry::Vec2;

/// A grid of `nx × ny` cells covering `origin .. origin + size`, numbered row by row from the
/// lower-left (`c = i + nx·j`; with triangles, elements `2c` and `2c + 1`; crossed, `4c` to
/// `4c + 3` about the cell's centre, which is vertex `(nx + 1)(ny + 1) + c`).
///
/// # Errors
/// `nx` or `ny` is zero, or `origin` and `size` give cells of no area, clockwise cells (`size`
/// negative in one direction) or coordinates that are not finite.
pub fn grid(
    body: &str,
    origin: Vec2,
    size: Vec2,
    nx: usize,
    ny: usize,
    cell: Cell,
) -> Result<Mesh> {
    let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            vertices.push(
                origin + Vec2::new(size.x * i as f64 / nx as f64, size.y * j as f64 / ny as f64),
            );
        }
    }
    let v = |i: usize, j: usize| (i + (nx + 1) * j) as u32;
    let corners = vertices.len();
    if cell == Cell::Crossed {
        for j in 0..ny {
            for i in 0..nx {
                vertices.push(
                    origin
                        + Vec2::new(
                            size.x * (i as f64 + 0.5) / nx as f64,
                            size.y * (j as f64 + 0.5) / ny as f64,
                        ),
                );
            }
        }
    }
    let mut cells = Vec::with_capacity(nx * ny * cell.per_cell());
    for j in 0..ny {
        for i in 0..nx {
            let (p00, p10, p11, p01) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
            match cell {
                Cell::Rect => cells.push(vec![p00, p10, p11, p01]),
                Cell::Tri => {
                    cells.push(vec![p00, p10, p11]);
                    cells.push(vec![p00, p11, p01]);
                }
                Cell::Crossed => {
                    let m = (corners + i + nx * j) as u32;
                    cells.push(vec![p00, p10, m]);
                    cells.push(vec![p10, p11, m]);
                    cells.push(vec![p11, p01, m]);
                    cells.push(vec![p01, p00, m]);
                }
            }
        }
    }
    Mesh::build(body, vertices, &cells, Checks::Generated)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_of_a_rectangle_grid() {
        let m = grid("b", Vec2::zeros(), Vec2::new(2.0, 1.0), 4, 3, Cell::Rect).unwrap();
        assert_eq!(m.n_cells(), 12);
        assert_eq!(m.shared.len(), 3 * 3 + 4 * 2);
        assert_eq!(m.boundary.len(), 2 * (4 + 3));
    }

    #[test]
    fn triangle_numbering_follows_the_design() {
        let m = grid("b", Vec2::zeros(), Vec2::new(2.0, 1.0), 2, 1, Cell::Tri).unwrap();
        assert_eq!(m.n_cells(), 4);
        // Rectangle 1 (i = 1, j = 0): element 2 is its lower-right triangle.
        let p = m.cell_points(2);
        assert_eq!(
            p,
            vec![
                Vec2::new(1.0, 0.0),
                Vec2::new(2.0, 0.0),
                Vec2::new(2.0, 1.0)
            ]
        );
        assert_eq!(m.shared.len(), 2 + 1);
    }

    /// Crossed: four triangles about each centre, 4 shared edges inside each cell and the
    /// grid's own between cells, each cell's triangles a quarter of its area.
    #[test]
    fn crossed_cells_meet_at_their_centres() {
        let m = grid("b", Vec2::zeros(), Vec2::new(2.0, 1.0), 2, 1, Cell::Crossed).unwrap();
        assert_eq!(m.n_cells(), 8);
        assert_eq!(m.shared.len(), 2 * 4 + 1);
        assert_eq!(m.boundary.len(), 2 * (2 + 1));
        // Cell 1 (i = 1): its right triangle, element 5, about the centre (1.5, 0.5).
        assert_eq!(
            m.cell_points(5),
            vec![
                Vec2::new(2.0, 0.0),
                Vec2::new(2.0, 1.0),
                Vec2::new(1.5, 0.5)
            ]
        );
    }
}
