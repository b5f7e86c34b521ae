//! ParaView output (`output.vtk`): one legacy `.vtk` file of element polygons per recorded
//! step, written with `vtkio`, and a `.pvd` collection that ParaView opens as a time series.
//! Elements are drawn separately (their vertices are not shared), displaced by `N_e(x) U_e`.

use crate::error::{Error, Result};
use crate::integrator::Snapshot;
use crate::model::Model;
use std::path::{Path, PathBuf};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, IOBuffer, UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

/// A series of frames in `DIR/vtk/` and its collection `DIR/series.pvd`.
pub struct VtkSeries {
    dir: PathBuf,
    frames: Vec<(f64, String)>,
}

impl VtkSeries {
    /// Creates `DIR/vtk/`.
    pub fn create(dir: &Path) -> Result<VtkSeries> {
        let frames_dir = dir.join("vtk");
        std::fs::create_dir_all(&frames_dir).map_err(|e| Error::io(&frames_dir, e))?;
        Ok(VtkSeries { dir: dir.to_path_buf(), frames: Vec::new() })
    }

    /// Writes the frame of one recorded step, then rewrites the collection so that it lists
    /// every frame written so far.
    pub fn write(&mut self, model: &Model, s: &Snapshot) -> Result<()> {
        let nd = model.formulation.ndof();
        let (mut points, mut conn) = (Vec::new(), Vec::new());
        let (mut disp, mut vel, mut rot, mut body) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for b in &model.bodies {
            for c in 0..b.mesh.n_cells() {
                let e = b.first_element + c;
                let (u, v) = (&s.u[e * nd..(e + 1) * nd], &s.v[e * nd..(e + 1) * nd]);
                let xe = model.elements[e].props.centroid;
                let cell = b.mesh.cell(c);
                conn.push(cell.len() as u32);
                for &k in cell {
                    let x = b.mesh.vertices[k as usize];
                    let p = x + model.formulation.displacement(u, x - xe);
                    conn.push((points.len() / 3) as u32);
                    points.extend([p.x, p.y, 0.0]);
                }
                disp.extend([u[0], u[1], 0.0]);
                vel.extend([v[0], v[1], 0.0]);
                rot.push(u[2]);
                body.push(model.elements[e].body as f64);
            }
        }
        let n_cells = model.elements.len();
        let vtk = Vtk {
            version: Version::new((4, 2)),
            title: format!("{} t = {:e} s", model.name, s.t),
            byte_order: ByteOrder::BigEndian,
            file_path: None,
            data: DataSet::inline(UnstructuredGridPiece {
                points: IOBuffer::F64(points),
                cells: Cells {
                    cell_verts: VertexNumbers::Legacy { num_cells: n_cells as u32, vertices: conn },
                    types: vec![CellType::Polygon; n_cells],
                },
                data: Attributes {
                    point: Vec::new(),
                    cell: vec![
                        Attribute::vectors("displacement").with_data(disp),
                        Attribute::vectors("velocity").with_data(vel),
                        Attribute::scalars("rotation", 1).with_data(rot),
                        Attribute::scalars("body", 1).with_data(body),
                    ],
                },
            }),
        };
        let name = format!("vtk/step_{:09}.vtk", s.step);
        let path = self.dir.join(&name);
        vtk.export_be(&path).map_err(|e| Error::io(&path, std::io::Error::other(e.to_string())))?;
        self.frames.push((s.t, name));
        self.write_collection()
    }

    fn write_collection(&self) -> Result<()> {
        let mut xml = String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n");
        for (t, f) in &self.frames {
            xml.push_str(&format!("    <DataSet timestep=\"{t:e}\" part=\"0\" file=\"{f}\"/>\n"));
        }
        xml.push_str("  </Collection>\n</VTKFile>\n");
        let path = self.dir.join("series.pvd");
        std::fs::write(&path, xml).map_err(|e| Error::io(&path, e))
    }
}
