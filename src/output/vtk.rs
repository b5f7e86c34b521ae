//! ParaView output (`output.vtk`): one VTK XML unstructured grid (`.vtu`) of the elements per
//! recorded step, written with `vtkio`, and a `.pvd` collection that ParaView opens as a time
//! series (its reader takes XML files only). Elements are drawn separately (their vertices are
//! not shared) in their current place, rigid elements with their finite rotation
//! ([`Formulation::current_position`](crate::model::formulation::Formulation::current_position)),
//! as
//! triangles, quadrilaterals or polygons.
//!
//! A run whose interfaces can fail also writes the cracks: per recorded step a grid of lines,
//! one per interface that can fail, with its state, in `DIR/cracks/` and their collection
//! `DIR/cracks.pvd` ([`write_cracks`]). They are a series of their own so that the element frames
//! keep one cell per element and only the elements' arrays, whatever the scene.

use crate::error::{Error, Result};
use crate::force::failure::{InterfaceFailure, InterfaceStatus, PlasticForces};
use crate::force::yielding::PlasticElements;
use crate::mesh::geometry::Vec2;
use crate::model::{Interface, Model, GROUND};
use crate::step::integrator::Snapshot;
use std::path::{Path, PathBuf};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, IOBuffer, UnstructuredGridPiece,
    Version, VertexNumbers, Vtk,
};

/// A series of frames in `DIR/vtk/` and its collection `DIR/series.pvd`, and, when the
/// model's interfaces can fail, the cracks of the same steps in `DIR/cracks/` and
/// `DIR/cracks.pvd`. Each frame is written whole under a temporary name and renamed; the
/// collections then gain their entries, each in one write over its closing tags, so that they
/// list exactly the frames written, even after the process is killed, at a cost that does not
/// grow with the number of frames.
pub struct VtkSeries<'a> {
    dir: PathBuf,
    frames: Vec<(f64, String)>,
    collection: Collection,
    /// The plastic forces that report the interfaces' states, and the cracks' collection.
    cracks: Option<(&'a dyn PlasticForces, Collection)>,
    /// The elements that may yield, whose plastic strains the frames show.
    yielding: Option<&'a PlasticElements>,
}

const HEAD: &str =
    "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n";
const TAIL: &str = "  </Collection>\n</VTKFile>\n";

fn entry(t: f64, name: &str) -> String {
    format!("    <DataSet timestep=\"{t:e}\" part=\"0\" file=\"{name}\"/>\n")
}

/// The folder of the crack frames and their collection, under a run's folder.
pub const CRACKS: (&str, &str) = ("cracks", "cracks.pvd");

/// The crack frame (name under `DIR`) of the element frame `frame`: `vtk/step_N.vtu` →
/// `cracks/step_N.vtu`.
pub fn crack_frame(frame: &str) -> String {
    let name = frame.rsplit('/').next().unwrap_or(frame);
    format!("{}/{name}", CRACKS.0)
}

/// An open collection file that grows by one entry per frame.
struct Collection {
    path: PathBuf,
    file: std::fs::File,
    /// Where the closing tags start.
    tail: u64,
}

impl Collection {
    /// Writes the collection `path` listing `frames` and keeps it open to add more (through
    /// the file written, never through a link at `path`).
    fn open(path: PathBuf, frames: &[(f64, String)]) -> Result<Collection> {
        let xml = collection_xml(frames);
        let file = crate::output::write_atomic_open(&path, xml.as_bytes())?;
        let tail = (xml.len() - TAIL.len()) as u64;
        Ok(Collection { path, file, tail })
    }

    /// Adds the frame `name` at time `t`, in one write over the closing tags.
    fn append(&mut self, t: f64, name: &str) -> Result<()> {
        use std::io::{Seek, SeekFrom, Write};
        let line = entry(t, name);
        let write = |file: &mut std::fs::File, at: u64, text: &str| {
            file.seek(SeekFrom::Start(at))
                .and_then(|_| file.write_all(text.as_bytes()))
        };
        if let Err(e) = write(&mut self.file, self.tail, &format!("{line}{TAIL}")) {
            // Put the closing tags back where they were: the collection stays whole.
            let _ = self
                .file
                .set_len(self.tail)
                .and_then(|_| write(&mut self.file, self.tail, TAIL));
            return Err(Error::io(&self.path, e));
        }
        self.tail += line.len() as u64;
        Ok(())
    }
}

/// Creates `dir` and removes the frames in it that `keep` (names under its parent) does not
/// list.
fn prune(dir: &Path, keep: &std::collections::HashSet<String>) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let folder = dir.file_name().and_then(|n| n.to_str()).unwrap_or("");
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if is_frame(name) && !keep.contains(&format!("{folder}/{name}")) {
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    Ok(())
}

impl<'a> VtkSeries<'a> {
    /// Creates `DIR/vtk/` and an empty collection; with `plastic` (a model whose interfaces can
    /// fail) also `DIR/cracks/` and its empty collection.
    ///
    /// # Errors
    /// As [`VtkSeries::resume`] with no frames: the folders cannot be created or cleared of an
    /// earlier run's frames, or a collection cannot be written.
    pub fn create(
        dir: &Path,
        plastic: Option<&'a dyn PlasticForces>,
        yielding: Option<&'a PlasticElements>,
    ) -> Result<VtkSeries<'a>> {
        Self::resume(dir, Vec::new(), plastic, yielding)
    }

    /// Goes on with the frames `frames` (time, name under `DIR`) of an earlier run: removes the
    /// frames it wrote after them (and their cracks) and writes the collections of these.
    ///
    /// # Errors
    /// `DIR/vtk/` or `DIR/cracks/` cannot be created, listed or cleared of the later frames, or
    /// `DIR/series.pvd` or `DIR/cracks.pvd` cannot be written.
    pub fn resume(
        dir: &Path,
        frames: Vec<(f64, String)>,
        plastic: Option<&'a dyn PlasticForces>,
        yielding: Option<&'a PlasticElements>,
    ) -> Result<VtkSeries<'a>> {
        prune(
            &dir.join("vtk"),
            &frames.iter().map(|(_, f)| f.clone()).collect(),
        )?;
        let collection = Collection::open(dir.join("series.pvd"), &frames)?;
        let cracks = match plastic {
            None => None,
            Some(plastic) => {
                let cracks: Vec<(f64, String)> =
                    frames.iter().map(|(t, f)| (*t, crack_frame(f))).collect();
                prune(
                    &dir.join(CRACKS.0),
                    &cracks.iter().map(|(_, f)| f.clone()).collect(),
                )?;
                Some((plastic, Collection::open(dir.join(CRACKS.1), &cracks)?))
            }
        };
        Ok(VtkSeries {
            dir: dir.to_path_buf(),
            frames,
            collection,
            cracks,
            yielding,
        })
    }

    /// The frames written so far: time and name under `DIR`.
    pub fn frames(&self) -> &[(f64, String)] {
        &self.frames
    }

    /// Writes the frame of one recorded step (and its cracks), then adds it to the
    /// collection(s).
    ///
    /// # Errors
    /// The frame or its cracks cannot be written, or a collection cannot gain its entry (it is then
    /// left whole, without it).
    pub fn write(&mut self, model: &Model, s: &Snapshot) -> Result<()> {
        let name = format!("vtk/step_{:09}.vtu", s.step);
        let plastic = match (self.yielding, s.elements) {
            (Some(y), Some(state)) => y.per_element(state, model.elements.len()),
            _ => Vec::new(),
        };
        write_frame(
            &self.dir.join(&name),
            model,
            (s.u, s.v),
            &plastic,
            Placement::Current,
        )?;
        let cracks = match (&self.cracks, s.failure) {
            (Some((plastic, _)), Some(state)) => {
                let crack = crack_frame(&name);
                let report = plastic.report(state);
                write_cracks(&self.dir.join(&crack), model, s.u, &report)?;
                Some(crack)
            }
            _ => None,
        };
        self.collection.append(s.t, &name)?;
        if let (Some((_, collection)), Some(crack)) = (self.cracks.as_mut(), cracks) {
            collection.append(s.t, &crack)?;
        }
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

impl Placement {
    /// Where the reference point `x` of element `e` is placed, with the element's DOFs `ue`.
    pub fn position(self, model: &Model, e: usize, ue: &[f64], x: Vec2) -> Vec2 {
        let xe = model.elements[e].props.centroid;
        match self {
            Placement::Current => model.formulation.current_position(xe, ue, x - xe),
            Placement::Linear => x + model.formulation.displacement(ue, x - xe),
        }
    }
}

/// The edge of the interface `i` placed by `placement` with the displacements `u`: each end
/// midway between where it is on side `a` and on side `b` (on side `a` alone for a ground
/// spring), so that a crack is drawn in the middle of its opening.
pub fn interface_edge(model: &Model, u: &[f64], i: &Interface, placement: Placement) -> [Vec2; 2] {
    let nd = model.formulation.ndof();
    let on = |e: u32, x: Vec2| {
        let e = e as usize;
        placement.position(model, e, &u[e * nd..(e + 1) * nd], x)
    };
    [i.p1, i.p2].map(|x| {
        if i.b == GROUND {
            on(i.a, x)
        } else {
            0.5 * (on(i.a, x) + on(i.b, x))
        }
    })
}

/// `1` for a `yielding` interface, `2` for a `broken` one, `3` for one `released` to contact,
/// `0` for an `elastic` one.
pub fn status_code(status: InterfaceStatus) -> i32 {
    match status {
        InterfaceStatus::Elastic => 0,
        InterfaceStatus::Yielding => 1,
        InterfaceStatus::Broken => 2,
        InterfaceStatus::Released => 3,
    }
}

/// Writes one VTK XML unstructured grid (`.vtu`) of the elements placed by `placement`, with
/// cell data `displacement`, `velocity`, `rotation` and `body` (hybrid: `strain`, `stress`).
/// Cells of 3 and 4 vertices are written as VTK triangles and quadrilaterals, others as polygons.
///
/// # Errors
/// vtkio cannot encode the grid, or `path` cannot be written.
///
/// # Panics
/// `u` or `v` is shorter than `ndof × elements`.
pub fn write_frame(
    path: &Path,
    model: &Model,
    (u, v): (&[f64], &[f64]),
    plastic: &[([f64; 3], bool)],
    placement: Placement,
) -> Result<()> {
    let nd = model.formulation.ndof();
    let (mut points, mut conn, mut offsets, mut types) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut disp, mut vel, mut rot, mut body) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut strain, mut stress): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    let (mut plastic_strain, mut yielding) = (Vec::new(), Vec::new());
    for b in &model.bodies {
        for c in 0..b.mesh.n_cells() {
            let e = b.first_element + c;
            let (ue, ve) = (&u[e * nd..(e + 1) * nd], &v[e * nd..(e + 1) * nd]);
            let p = plastic.get(e).copied();
            if let Some(s) =
                crate::output::element_stress(model, e, ue, p.map(|p| p.0).unwrap_or_default())
            {
                strain.extend_from_slice(&ue[3..6]);
                stress.extend(s);
            }
            if let Some((ep, flows)) = p {
                plastic_strain.extend(ep);
                yielding.push(i32::from(flows));
            }
            let cell = b.mesh.cell(c);
            for &k in cell {
                let p = placement.position(model, e, ue, b.mesh.vertices[k as usize]);
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
    if !plastic.is_empty() {
        // ε_p and whether the element flowed at the step: elements that yield (issue 43).
        cell.push(Attribute::scalars("plastic_strain", 3).with_data(plastic_strain));
        cell.push(Attribute::scalars("yielding", 1).with_data(yielding));
    }
    write_grid(path, points, (conn, offsets), types, cell)
}

/// Writes the cracks of one recorded step as a VTK XML unstructured grid (`.vtu`): a line
/// (`VTK_LINE`) per failing interface of `report`, in its order, on its edge placed as
/// [`interface_edge`] says with the finite rotations of the run, and the cell data
/// `interface_status` (0 elastic, 1 yielding, 2 broken: the cracks are the lines above 0),
/// `crack_opening` and `crack_slip` (the mean plastic opening and slip, m), `dissipated` (J)
/// and `interface` (its index in `Model::interfaces`, as in `final_state.json`). Every frame
/// has the same lines, so that cell `k` is the same interface throughout a run, and none is
/// empty (meshio 5.3 cannot read a grid without cells).
///
/// # Errors
/// vtkio cannot encode the grid, or `path` cannot be written.
///
/// # Panics
/// `report` names an interface the model does not have, or `u` is shorter than `ndof × elements`.
pub fn write_cracks(
    path: &Path,
    model: &Model,
    u: &[f64],
    report: &[InterfaceFailure],
) -> Result<()> {
    let mut points = Vec::with_capacity(6 * report.len());
    for r in report {
        let edge = interface_edge(model, u, &model.interfaces[r.interface], Placement::Current);
        for p in edge {
            points.extend([p.x, p.y, 0.0]);
        }
    }
    let n = report.len() as u64;
    let data = |f: fn(&InterfaceFailure) -> f64| report.iter().map(f).collect::<Vec<_>>();
    let status: Vec<i32> = report.iter().map(|r| status_code(r.status)).collect();
    let index: Vec<i64> = report.iter().map(|r| r.interface as i64).collect();
    // The first scalars are the active ones, which ParaView colours by when it opens the file.
    let cell = vec![
        Attribute::scalars("interface_status", 1).with_data(status),
        Attribute::scalars("crack_opening", 1).with_data(data(|r| r.opening)),
        Attribute::scalars("crack_slip", 1).with_data(data(|r| r.slip)),
        Attribute::scalars("dissipated", 1).with_data(data(|r| r.dissipated)),
        Attribute::scalars("interface", 1).with_data(index),
    ];
    write_grid(
        path,
        points,
        ((0..2 * n).collect(), (1..=n).map(|k| 2 * k).collect()),
        vec![CellType::Line; report.len()],
        cell,
    )
}

/// Writes one unstructured grid as a VTK XML file (`.vtu`, binary, inline): its points
/// (x, y, z), its cells as `(connectivity, offsets)` with their types, and the cell data;
/// through a temporary name ([`crate::output::write_atomic`]).
fn write_grid(
    path: &Path,
    points: Vec<f64>,
    (connectivity, offsets): (Vec<u64>, Vec<u64>),
    types: Vec<CellType>,
    cell: Vec<Attribute>,
) -> Result<()> {
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(points),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity,
                offsets,
            },
            types,
        },
        data: Attributes {
            point: Vec::new(),
            cell,
        },
    };
    let vtk = Vtk {
        version: Version::new((1, 0)),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(piece),
    };
    let fail = |e: String| Error::io(path, std::io::Error::other(e));
    let xml = vtkio::xml::VTKFile::try_from(vtk)
        .map_err(|e| fail(e.to_string()))?
        .to_string();
    // vtkio declares connectivity and offsets `UInt64`, which meshio cannot subtract from for
    // polygons; `Int64` has the same bytes for these values and every reader takes it.
    let mut xml = xml
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
    // vtkio leaves out `NumberOfCells` when there are none, and readers then refuse the piece.
    if !xml.contains("NumberOfCells=") {
        xml = xml.replacen(
            r#"NumberOfPoints="0""#,
            r#"NumberOfPoints="0" NumberOfCells="0""#,
            1,
        );
    }
    crate::output::write_atomic(path, xml.as_bytes())
}

/// Writes each mode shape as `DIR/mode_NNN.vtu` and the collection `DIR/modes.pvd` (one time
/// step per mode: its number), scaled so that the largest vertex displacement is a tenth of
/// the model's size (shapes are `M`-normalised, their scale is arbitrary).
///
/// # Errors
/// `dir` cannot be created, or a `mode_NNN.vtu` or `modes.pvd` cannot be written in it.
///
/// # Panics
/// A shape is shorter than `ndof × elements`.
pub fn write_mode_shapes(dir: &Path, model: &Model, shapes: &[Vec<f64>]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut frames = Vec::new();
    for (k, shape) in shapes.iter().enumerate() {
        let name = format!("mode_{:03}.vtu", k + 1);
        write_shape(&dir.join(&name), model, shape, &vec![0.0; shape.len()])?;
        frames.push(((k + 1) as f64, name));
    }
    write_collection(&dir.join("modes.pvd"), &frames)
}

/// Writes `shape` (DOFs over the model: a mode, a mechanism) as one frame, its displacement
/// scaled so that the largest displacement of an element's vertex (rotations and strains
/// included, [`crate::output::largest_vertex_displacement`]) is a tenth of the model's size,
/// with `v` as its velocity.
///
/// # Errors
/// As [`write_frame`].
pub fn write_shape(path: &Path, model: &Model, shape: &[f64], v: &[f64]) -> Result<()> {
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
    let max = crate::output::largest_vertex_displacement(model, shape);
    let scale = if max > 0.0 { 0.1 * size / max } else { 1.0 };
    let u: Vec<f64> = shape.iter().map(|x| x * scale).collect();
    write_frame(path, model, (&u, v), &[], Placement::Linear)
}

/// Writes a collection listing `frames` (time, file name relative to the collection).
///
/// # Errors
/// `path` cannot be written ([`crate::output::write_atomic`]).
pub fn write_collection(path: &Path, frames: &[(f64, String)]) -> Result<()> {
    crate::output::write_atomic(path, collection_xml(frames).as_bytes())
}

/// The collection listing `frames`, ending with [`TAIL`].
fn collection_xml(frames: &[(f64, String)]) -> String {
    let mut xml = String::from(HEAD);
    for (t, f) in frames {
        xml.push_str(&entry(*t, f));
    }
    xml.push_str(TAIL);
    xml
}
