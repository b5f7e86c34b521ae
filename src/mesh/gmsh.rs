//! Meshes from gmsh: MSH 4.1 files (ASCII or binary, read by the `mshio` crate) of 3-node
//! triangles and 4-node quadrilaterals. Physical groups of 2-node lines name boundary edges,
//! which supports and loads select by name (`"edge": "clamp"`), beside the bounding-box sides.
//!
//! Only the nodes that cells use become vertices, in the order of their gmsh tags; cells keep
//! the file's order and are turned counter-clockwise where gmsh wrote them clockwise.

use super::{Checks, Mesh};
use crate::error::{Error, Result};
use crate::mesh::geometry::{area_properties, Vec2};
use mshio::mshfile::ElementType;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Boundary edges named by a gmsh physical group: vertex pairs, each sorted.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeGroup {
    /// The physical group's name.
    pub name: String,
    /// Its edges as vertex pairs `[low, high]` into the mesh's vertices.
    pub edges: Vec<[u32; 2]>,
}

/// The largest MSH file read (bytes).
pub const MAX_MESH_BYTES: u64 = 2 << 30;

/// Reads the mesh of body `body` from the MSH 4.1 file `path`, named in the scene at `at`
/// (`bodies[0].mesh`).
///
/// # Errors
/// `path` cannot be read, is not a regular file or is larger than [`MAX_MESH_BYTES`]; it is not an
/// MSH 4.1 file with 8-byte data, of 3-node triangles and 4-node quadrilaterals with 2-node lines
/// for groups; or its cells do not form a valid mesh (as [`Mesh::from_polygons`] checks), or a
/// group's line is not an edge of a cell.
pub fn read(body: &str, at: &str, path: &Path) -> Result<Mesh> {
    let bytes = crate::input::scene::read_limited(path, MAX_MESH_BYTES, "a mesh file")?;
    let field = format!("{at}.path");
    let fail = |message: String| {
        Error::scene(
            field.clone(),
            format!("{} (body `{body}`): {message}", path.display()),
        )
    };
    check_header(&bytes, &fail)?;
    // The reader panics on some malformed files; that is an error in the file, not a crash.
    let parsed = std::panic::catch_unwind(|| mshio::parse_msh_bytes(&bytes))
        .map_err(|_| fail("the MSH 4.1 reader failed on malformed data in this file".into()))?;
    let msh = parsed.map_err(|e| fail(format!("cannot parse the MSH 4.1 file: {e}")))?;
    let nodes = msh
        .data
        .nodes
        .as_ref()
        .ok_or_else(|| fail("the file has no `$Nodes` section".into()))?;
    let coordinates = node_coordinates(nodes);
    let (cells, lines, named) = cells_and_groups(&msh, &bytes, &fail)?;
    if cells.is_empty() && (!lines.is_empty() || named) {
        // gmsh saves only the elements of physical groups once any is defined.
        return Err(fail(
            "the file has no triangles or quadrilaterals, only elements of physical groups: \
            add a `Physical Surface(\"body\") = {...};` for the meshed surface to the .geo (gmsh \
                saves only the elements of physical groups once one is defined)"
                .into(),
        ));
    }
    if cells.is_empty() {
        return Err(fail(
            "the file has no triangles or quadrilaterals: mesh the surface in 2D (`gmsh -2`)"
                .into(),
        ));
    }
    // Vertices: the nodes the cells use, in tag order.
    let mut used: Vec<u64> = cells.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    let index: HashMap<u64, u32> = used
        .iter()
        .enumerate()
        .map(|(i, &t)| (t, i as u32))
        .collect();
    let mut vertices = Vec::with_capacity(used.len());
    for t in &used {
        vertices.push(
            *coordinates
                .get(t)
                .ok_or_else(|| fail(format!("node {t} is used by a cell but not defined")))?,
        );
    }
    let cells: Vec<Vec<u32>> = cells
        .iter()
        .map(|c| {
            let mut c: Vec<u32> = c.iter().map(|t| index[t]).collect();
            let p: Vec<Vec2> = c.iter().map(|&v| vertices[v as usize]).collect();
            if area_properties(&p).area < 0.0 {
                c.reverse();
            }
            c
        })
        .collect();
    let mut mesh = Mesh::build(body, vertices, &cells, Checks::UserInput)?;
    for (name, pairs) in lines {
        let mut edges = Vec::with_capacity(pairs.len());
        for [p, q] in pairs {
            let (Some(&a), Some(&b)) = (index.get(&p), index.get(&q)) else {
                return Err(fail(format!(
                    "group `{name}`: the line {p}–{q} is not an edge of any cell"
                )));
            };
            edges.push([a.min(b), a.max(b)]);
        }
        mesh.groups.push(EdgeGroup { name, edges });
    }
    Ok(mesh)
}

/// Refuses a file that is not MSH 4.1 with 8-byte data, ASCII or binary.
fn check_header(bytes: &[u8], fail: &dyn Fn(String) -> Error) -> Result<()> {
    let header = format_header(bytes)
        .ok_or_else(|| fail("not a gmsh MSH file: no `$MeshFormat` header".into()))?;
    let [version, file_type, data_size] =
        [0, 1, 2].map(|i| header.get(i).map_or("", String::as_str));
    if version != "4.1" {
        return Err(fail(format!(
            "MSH version {version} is not supported; save the mesh as MSH 4.1 \
            (`gmsh -2 -format msh41 file.geo`)"
        )));
    }
    if !matches!(file_type, "0" | "1") || data_size != "8" {
        return Err(fail(format!(
            "the `$MeshFormat` line reads `{}`: MSH 4.1 has file type 0 (ASCII) or 1 (binary) and \
                data size 8",
            header.join(" ")
        )));
    }
    Ok(())
}

/// Node tag → coordinates. Without a tag map a block's tags run on from the smallest tag.
fn node_coordinates(nodes: &mshio::mshfile::Nodes<u64, i32, f64>) -> HashMap<u64, Vec2> {
    let mut coordinates: HashMap<u64, Vec2> = HashMap::new();
    let mut next = nodes.min_node_tag;
    for block in &nodes.node_blocks {
        let tags: Vec<u64> = match &block.node_tags {
            Some(map) => {
                let mut t = vec![0; block.nodes.len()];
                for (&tag, &i) in map {
                    t[i] = tag;
                }
                t
            }
            None => (next..next + block.nodes.len() as u64).collect(),
        };
        next += block.nodes.len() as u64;
        for (tag, n) in tags.into_iter().zip(&block.nodes) {
            coordinates.insert(tag, Vec2::new(n.x, n.y));
        }
    }
    coordinates
}

/// The cells (node tags of each triangle and quadrilateral) and the named groups of lines
/// (node-tag pairs of each 2-node line, by physical group) of a parsed file; and whether it
/// names any physical group.
#[allow(clippy::type_complexity)]
fn cells_and_groups(
    msh: &mshio::MshFile<u64, i32, f64>,
    bytes: &[u8],
    fail: &dyn Fn(String) -> Error,
) -> Result<(Vec<Vec<u64>>, BTreeMap<String, Vec<[u64; 2]>>, bool)> {
    let elements = msh
        .data
        .elements
        .as_ref()
        .ok_or_else(|| fail("the file has no `$Elements` section".into()))?;
    let names = physical_names(bytes);
    let curve_groups: HashMap<i32, Vec<i32>> =
        msh.data.entities.as_ref().map_or_else(HashMap::new, |e| {
            e.curves
                .iter()
                .map(|c| (c.tag, c.physical_tags.clone()))
                .collect()
        });
    let mut cells: Vec<Vec<u64>> = Vec::new();
    let mut lines: BTreeMap<String, Vec<[u64; 2]>> = BTreeMap::new();
    for block in &elements.element_blocks {
        match block.element_type {
            ElementType::Tri3 | ElementType::Qua4 => {
                cells.extend(block.elements.iter().map(|e| e.nodes.clone()))
            }
            ElementType::Lin2 => {
                for &group in curve_groups.get(&block.entity_tag).into_iter().flatten() {
                    let name = names
                        .get(&(1, group))
                        .cloned()
                        .unwrap_or_else(|| group.to_string());
                    lines
                        .entry(name)
                        .or_default()
                        .extend(block.elements.iter().map(|e| [e.nodes[0], e.nodes[1]]));
                }
            }
            ElementType::Pnt => {}
            other => {
                let tag = block.elements.first().map_or(0, |e| e.element_tag);
                return Err(fail(format!(
                    "element {tag} is of type {other:?}, which is not supported: use 3-node triangles or 4-node quadrilaterals \
                     (first order, `Mesh.ElementOrder = 1`) for cells and 2-node lines for groups"
                )));
            }
        }
    }
    Ok((cells, lines, !names.is_empty()))
}

/// The words of the `$MeshFormat` line: version, file type, data size (the header is text in
/// binary files too).
fn format_header(bytes: &[u8]) -> Option<Vec<String>> {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(256)]).into_owned();
    let mut lines = head.lines().map(str::trim);
    lines.find(|l| *l == "$MeshFormat")?;
    let words: Vec<String> = lines
        .next()?
        .split_whitespace()
        .map(str::to_string)
        .collect();
    (!words.is_empty()).then_some(words)
}

/// `(dimension, tag) → name` from the `$PhysicalNames` section (text in binary files too),
/// which `mshio` does not read.
fn physical_names(bytes: &[u8]) -> HashMap<(i32, i32), String> {
    let mut out = HashMap::new();
    let Some(start) = bytes.windows(14).position(|w| w == b"$PhysicalNames") else {
        return out;
    };
    let end = bytes[start..]
        .windows(17)
        .position(|w| w == b"$EndPhysicalNames")
        .map_or(bytes.len(), |e| start + e);
    let text = String::from_utf8_lossy(&bytes[start..end]).into_owned();
    for line in text.lines().skip(2) {
        let mut parts = line.trim().splitn(3, ' ');
        if let (Some(dim), Some(tag), Some(name)) = (parts.next(), parts.next(), parts.next()) {
            if let (Ok(dim), Ok(tag)) = (dim.parse(), tag.parse()) {
                out.insert((dim, tag), name.trim().trim_matches('"').to_string());
            }
        }
    }
    out
}
