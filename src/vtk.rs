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
        let name = format!("vtk/step_{:09}.vtk", s.step);
        write_frame(&self.dir.join(&name), model, s.u, s.v, &format!("{} t = {:e} s", model.name, s.t))?;
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

/// Writes one legacy VTK file of the element polygons displaced by `N_e(x) U_e`, with cell data
/// `displacement`, `velocity`, `rotation` and `body`.
pub fn write_frame(path: &Path, model: &Model, u: &[f64], v: &[f64], title: &str) -> Result<()> {
    let nd = model.formulation.ndof();
    let (mut points, mut conn) = (Vec::new(), Vec::new());
    let (mut disp, mut vel, mut rot, mut body) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut strain, mut stress): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for b in &model.bodies {
        for c in 0..b.mesh.n_cells() {
            let e = b.first_element + c;
            let (ue, ve) = (&u[e * nd..(e + 1) * nd], &v[e * nd..(e + 1) * nd]);
            if let Some(s) = crate::output::element_stress(model, e, ue) {
                strain.extend_from_slice(&ue[3..6]);
                stress.extend(s);
            }
            let xe = model.elements[e].props.centroid;
            let cell = b.mesh.cell(c);
            conn.push(cell.len() as u32);
            for &k in cell {
                let x = b.mesh.vertices[k as usize];
                let p = x + model.formulation.displacement(ue, x - xe);
                conn.push((points.len() / 3) as u32);
                points.extend([p.x, p.y, 0.0]);
            }
            disp.extend([ue[0], ue[1], 0.0]);
            vel.extend([ve[0], ve[1], 0.0]);
            rot.push(ue[2]);
            body.push(model.elements[e].body as f64);
        }
    }
    let n_cells = model.elements.len();
    let mut cell = vec![
        Attribute::vectors("displacement").with_data(disp),
        Attribute::vectors("velocity").with_data(vel),
        Attribute::scalars("rotation", 1).with_data(rot),
        Attribute::scalars("body", 1).with_data(body),
    ];
    if nd == 6 {
        // (ε_x, ε_y, γ_xy) and (σ_x, σ_y, τ_xy) = D ε of the hybrid formulation.
        cell.push(Attribute::scalars("strain", 3).with_data(strain));
        cell.push(Attribute::scalars("stress", 3).with_data(stress));
    }
    let vtk = Vtk {
        version: Version::new((4, 2)),
        title: title.to_string(),
        byte_order: ByteOrder::BigEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: IOBuffer::F64(points),
            cells: Cells {
                cell_verts: VertexNumbers::Legacy { num_cells: n_cells as u32, vertices: conn },
                types: vec![CellType::Polygon; n_cells],
            },
            data: Attributes { point: Vec::new(), cell },
        }),
    };
    vtk.export_be(path).map_err(|e| Error::io(path, std::io::Error::other(e.to_string())))
}

/// Writes each mode shape as `DIR/mode_NNN.vtk`, scaled so that the largest translation is a
/// tenth of the model's size (shapes are `M`-normalised, their scale is arbitrary).
pub fn write_mode_shapes(dir: &Path, model: &Model, modes: &crate::eigen::Modes) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let (mut lo, mut hi) = (crate::geometry::Vec2::repeat(f64::INFINITY), crate::geometry::Vec2::repeat(f64::NEG_INFINITY));
    for b in &model.bodies {
        let (l, h) = b.mesh.bounding_box();
        lo = lo.inf(&l);
        hi = hi.sup(&h);
    }
    let size = (hi - lo).norm();
    let nd = model.formulation.ndof();
    for (k, (shape, omega)) in modes.shapes.iter().zip(&modes.omega).enumerate() {
        let max = (0..model.elements.len()).map(|e| shape[e * nd].hypot(shape[e * nd + 1])).fold(0.0, f64::max);
        let scale = if max > 0.0 { 0.1 * size / max } else { 1.0 };
        let u: Vec<f64> = shape.iter().map(|x| x * scale).collect();
        let title = format!("{} mode {} f = {:e} Hz", model.name, k + 1, omega / (2.0 * std::f64::consts::PI));
        write_frame(&dir.join(format!("mode_{:03}.vtk", k + 1)), model, &u, &vec![0.0; u.len()], &title)?;
    }
    Ok(())
}
