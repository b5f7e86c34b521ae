//! ParaView output (`output.vtk`): one VTK XML unstructured grid (`.vtu`) of the elements per
//! recorded step, written with `vtkio`, and a `.pvd` collection that ParaView opens as a time
//! series (its reader takes XML files only). Elements are drawn separately (their vertices are
//! not shared) in their current place, rigid elements with their finite rotation
//! ([`Formulation::current_position`](crate::model::formulation::Formulation::current_position)),
//! as
//! triangles, quadrilaterals or polygons.

use crate::error::{Error, Result};
use crate::model::Model;
use crate::step::integrator::Snapshot;
use std::path::{Path, PathBuf};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, IOBuffer, UnstructuredGridPiece,
    Version, VertexNumbers, Vtk,
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

const HEAD: &str =
    "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n";
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
        let keep: std::collections::HashSet<&str> =
            frames.iter().map(|(_, f)| f.as_str()).collect();
        for entry in std::fs::read_dir(&frames_dir).map_err(|e| Error::io(&frames_dir, e))? {
            let path = entry.map_err(|e| Error::io(&frames_dir, e))?.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if is_frame(name) && !keep.contains(format!("vtk/{name}").as_str()) {
                std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
            }
        }
        let path = dir.join("series.pvd");
        write_collection(&path, &frames)?;
        let tail = (HEAD.len()
            + frames
                .iter()
                .map(|(t, f)| entry(*t, f).len())
                .sum::<usize>()) as u64;
        let collection = std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        Ok(VtkSeries {
            dir: dir.to_path_buf(),
            frames,
            collection,
            tail,
        })
    }

    /// The frames written so far: time and name under `DIR`.
    pub fn frames(&self) -> &[(f64, String)] {
        &self.frames
    }

    /// Writes the frame of one recorded step, then adds it to the collection.
    pub fn write(&mut self, model: &Model, s: &Snapshot) -> Result<()> {
        use std::io::{Seek, SeekFrom, Write};
        let name = format!("vtk/step_{:09}.vtu", s.step);
        let path = self.dir.join(&name);
        let tmp = crate::output::temporary(&path);
        if let Err(e) = write_frame(&tmp, model, s.u, s.v, Placement::Current) {
            let _ = std::fs::remove_file(&tmp);
            return Err(match e {
                Error::Io { source, .. } => Error::io(&path, source),
                other => other,
            });
        }
        std::fs::rename(&tmp, &path).map_err(|e| Error::io(&path, e))?;
        let line = entry(s.t, &name);
        let pvd = self.dir.join("series.pvd");
        let write = |file: &mut std::fs::File, at: u64, text: &str| {
            file.seek(SeekFrom::Start(at))
                .and_then(|_| file.write_all(text.as_bytes()))
        };
        if let Err(e) = write(&mut self.collection, self.tail, &format!("{line}{TAIL}")) {
            // Put the closing tags back where they were: the collection stays whole.
            let _ = self
                .collection
                .set_len(self.tail)
                .and_then(|_| write(&mut self.collection, self.tail, TAIL));
            return Err(Error::io(&pvd, e));
        }
        self.tail += line.len() as u64;
        self.frames.push((s.t, name));
        Ok(())
    }
}

/// Whether `name` is a frame's file name (`step_NNNNNNNNN.vtu`, or `.vtk` as earlier versions
/// wrote them), or a frame half written.
pub fn is_frame(name: &str) -> bool {
    let name = name.strip_prefix(".part-").unwrap_or(name);
    name.starts_with("step_") && (name.ends_with(".vtu") || name.ends_with(".vtk"))
}

/// Where a frame draws the elements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Placement {
    /// In their current place, with finite rotations (the frames of a run).
    Current,
    /// Moved by the linear `N_e(x) U_e` (a mode shape, linear by definition).
    Linear,
}

/// Writes one VTK XML unstructured grid (`.vtu`) of the elements placed by `placement`, with
/// cell data `displacement`, `velocity`, `rotation` and `body` (hybrid: `strain`, `stress`).
/// Cells of 3 and 4 vertices are written as VTK triangles and quadrilaterals, others as polygons.
pub fn write_frame(
    path: &Path,
    model: &Model,
    u: &[f64],
    v: &[f64],
    placement: Placement,
) -> Result<()> {
    let nd = model.formulation.ndof();
    let (mut points, mut conn, mut offsets, mut types) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
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
            for &k in cell {
                let x = b.mesh.vertices[k as usize];
                let p = match placement {
                    Placement::Current => model.formulation.current_position(xe, ue, x - xe),
                    Placement::Linear => x + model.formulation.displacement(ue, x - xe),
                };
                conn.push((points.len() / 3) as u64);
                points.extend([p.x, p.y, 0.0]);
            }
            offsets.push(conn.len() as u64);
            types.push(match cell.len() {
                3 => CellType::Triangle,
                4 => CellType::Quad,
                _ => CellType::Polygon,
            });
            disp.extend([ue[0], ue[1], 0.0]);
            vel.extend([ve[0], ve[1], 0.0]);
            rot.push(ue[2]);
            body.push(model.elements[e].body as f64);
        }
    }
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
        version: Version::new((1, 0)),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: IOBuffer::F64(points),
            cells: Cells {
                cell_verts: VertexNumbers::XML {
                    connectivity: conn,
                    offsets,
                },
                types,
            },
            data: Attributes {
                point: Vec::new(),
                cell,
            },
        }),
    };
    let fail = |e: String| Error::io(path, std::io::Error::other(e));
    let xml = vtkio::xml::VTKFile::try_from(vtk)
        .map_err(|e| fail(e.to_string()))?
        .to_string();
    // vtkio declares connectivity and offsets `UInt64`, which meshio cannot subtract from for
    // polygons; `Int64` has the same bytes for these values and every reader takes it.
    let xml = xml
        .replacen(
            r#"type="UInt64" Name="connectivity""#,
            r#"type="Int64" Name="connectivity""#,
            1,
        )
        .replacen(
            r#"type="UInt64" Name="offsets""#,
            r#"type="Int64" Name="offsets""#,
            1,
        );
    std::fs::write(path, xml).map_err(|e| Error::io(path, e))
}

/// Writes each mode shape as `DIR/mode_NNN.vtu` and the collection `DIR/modes.pvd` (one time
/// step per mode: its number), scaled so that the largest translation is a tenth of
/// the model's size (shapes are `M`-normalised, their scale is arbitrary).
pub fn write_mode_shapes(dir: &Path, model: &Model, shapes: &[Vec<f64>]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let (mut lo, mut hi) = (
        crate::mesh::geometry::Vec2::repeat(f64::INFINITY),
        crate::mesh::geometry::Vec2::repeat(f64::NEG_INFINITY),
    );
    for b in &model.bodies {
        let (l, h) = b.mesh.bounding_box();
        lo = lo.inf(&l);
        hi = hi.sup(&h);
    }
    let size = (hi - lo).norm();
    let nd = model.formulation.ndof();
    let mut frames = Vec::new();
    for (k, shape) in shapes.iter().enumerate() {
        let max = (0..model.elements.len())
            .map(|e| shape[e * nd].hypot(shape[e * nd + 1]))
            .fold(0.0, f64::max);
        let scale = if max > 0.0 { 0.1 * size / max } else { 1.0 };
        let u: Vec<f64> = shape.iter().map(|x| x * scale).collect();
        let name = format!("mode_{:03}.vtu", k + 1);
        write_frame(
            &dir.join(&name),
            model,
            &u,
            &vec![0.0; u.len()],
            Placement::Linear,
        )?;
        frames.push(((k + 1) as f64, name));
    }
    write_collection(&dir.join("modes.pvd"), &frames)
}

/// Writes a collection listing `frames` (time, file name relative to the collection).
pub fn write_collection(path: &Path, frames: &[(f64, String)]) -> Result<()> {
    let mut xml = String::from(HEAD);
    for (t, f) in frames {
        xml.push_str(&entry(*t, f));
    }
    xml.push_str(TAIL);
    crate::output::write_atomic(path, xml.as_bytes())
}
