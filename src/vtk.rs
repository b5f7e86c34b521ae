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

/// A series of frames in `DIR/vtk/` and its collection `DIR/series.pvd`. Each frame is written
/// whole under a temporary name and renamed; the collection then gains its entry in one write
/// over its closing tags, so that it lists exactly the frames written, even after the process
/// is killed, at a cost that does not grow with the number of frames.
pub struct VtkSeries {
    dir: PathBuf,
    frames: Vec<(f64, String)>,
    collection: std::fs::File,
    /// Where the closing tags of the collection start.
    tail: u64,
}

const HEAD: &str = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n";
const TAIL: &str = "  </Collection>\n</VTKFile>\n";

fn entry(t: f64, name: &str) -> String {
    format!("    <DataSet timestep=\"{t:e}\" part=\"0\" file=\"{name}\"/>\n")
}

impl VtkSeries {
    /// Creates `DIR/vtk/` and an empty collection.
    pub fn create(dir: &Path) -> Result<VtkSeries> {
        Self::resume(dir, Vec::new())
    }

    /// Goes on with the frames `frames` (time, name under `DIR`) of an earlier run: removes the
    /// frames it wrote after them and writes the collection of these.
    pub fn resume(dir: &Path, frames: Vec<(f64, String)>) -> Result<VtkSeries> {
        let frames_dir = dir.join("vtk");
        std::fs::create_dir_all(&frames_dir).map_err(|e| Error::io(&frames_dir, e))?;
        let keep: std::collections::HashSet<&str> = frames.iter().map(|(_, f)| f.as_str()).collect();
        for entry in std::fs::read_dir(&frames_dir).map_err(|e| Error::io(&frames_dir, e))? {
            let path = entry.map_err(|e| Error::io(&frames_dir, e))?.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if is_frame(name) && !keep.contains(format!("vtk/{name}").as_str()) {
                std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
            }
        }
        let mut xml = String::from(HEAD);
        for (t, f) in &frames {
            xml.push_str(&entry(*t, f));
        }
        let tail = xml.len() as u64;
        xml.push_str(TAIL);
        let path = dir.join("series.pvd");
        crate::output::write_atomic(&path, xml.as_bytes())?;
        let collection = std::fs::OpenOptions::new().write(true).open(&path).map_err(|e| Error::io(&path, e))?;
        Ok(VtkSeries { dir: dir.to_path_buf(), frames, collection, tail })
    }

    /// The frames written so far: time and name under `DIR`.
    pub fn frames(&self) -> &[(f64, String)] {
        &self.frames
    }

    /// Writes the frame of one recorded step, then adds it to the collection.
    pub fn write(&mut self, model: &Model, s: &Snapshot) -> Result<()> {
        use std::io::{Seek, SeekFrom, Write};
        let name = format!("vtk/step_{:09}.vtk", s.step);
        let path = self.dir.join(&name);
        let tmp = crate::output::temporary(&path);
        if let Err(e) = write_frame(&tmp, model, s.u, s.v, &format!("{} t = {:e} s", model.name, s.t)) {
            let _ = std::fs::remove_file(&tmp);
            return Err(match e {
                Error::Io { source, .. } => Error::io(&path, source),
                other => other,
            });
        }
        std::fs::rename(&tmp, &path).map_err(|e| Error::io(&path, e))?;
        let line = entry(s.t, &name);
        let pvd = self.dir.join("series.pvd");
        let write = |file: &mut std::fs::File, at: u64, text: &str| file.seek(SeekFrom::Start(at)).and_then(|_| file.write_all(text.as_bytes()));
        if let Err(e) = write(&mut self.collection, self.tail, &format!("{line}{TAIL}")) {
            // Put the closing tags back where they were: the collection stays whole.
            let _ = self.collection.set_len(self.tail).and_then(|_| write(&mut self.collection, self.tail, TAIL));
            return Err(Error::io(&pvd, e));
        }
        self.tail += line.len() as u64;
        self.frames.push((s.t, name));
        Ok(())
    }
}

/// Whether `name` is a frame's file name (`step_NNNNNNNNN.vtk`), or a frame half written.
pub fn is_frame(name: &str) -> bool {
    let name = name.strip_prefix(".part-").unwrap_or(name);
    name.starts_with("step_") && name.ends_with(".vtk")
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
