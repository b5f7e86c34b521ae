//! Meshes from gmsh (docs/scene.md, *`mesh`*): the shipped MSH 4.1 file gives the model of the
//! equivalent built-in grid, and unsupported files are refused with a clear message.

use rbsm::input::scene::Scene;
use rbsm::mesh::geometry::Vec2;
use rbsm::model::{Model, GROUND};
use std::collections::HashMap;

fn scene(name: &str) -> Scene {
    Scene::from_file(format!(
        "{}/examples/scenes/{name}.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

/// A key for a point, exact to well below the mesh's round-off.
fn key(p: Vec2) -> (i64, i64) {
    ((p.x * 1e9).round() as i64, (p.y * 1e9).round() as i64)
}

#[test]
fn the_shipped_msh_gives_the_model_of_the_built_in_grid() {
    let (grid, gmsh) = (
        Model::build(&scene("cantilever")).unwrap(),
        Model::build(&scene("cantilever_gmsh")).unwrap(),
    );
    assert_eq!(grid.elements.len(), 640);
    assert_eq!(gmsh.elements.len(), grid.elements.len());
    // Elements are matched by centroid: the same cells, areas and inertias. gmsh places the
    // nodes of a transfinite line to about 1e-13 m, so "the same" is to 1e-10 relative.
    let by_centroid: HashMap<_, usize> = grid
        .elements
        .iter()
        .enumerate()
        .map(|(i, e)| (key(e.props.centroid), i))
        .collect();
    let map: Vec<usize> = gmsh
        .elements
        .iter()
        .map(|e| by_centroid[&key(e.props.centroid)])
        .collect();
    for (i, e) in gmsh.elements.iter().enumerate() {
        let g = &grid.elements[map[i]];
        assert!((e.props.area - g.props.area).abs() <= 1e-10 * g.props.area);
        assert!((e.props.polar() - g.props.polar()).abs() <= 1e-10 * g.props.polar());
    }
    // The same interfaces (shared and ground), with the same springs.
    let pair = |a: u32, b: u32| {
        if b == GROUND {
            (a, GROUND)
        } else {
            (a.min(b), a.max(b))
        }
    };
    let springs: HashMap<_, _> = grid
        .interfaces
        .iter()
        .map(|i| (pair(i.a, i.b), (i.length, i.k_n, i.k_s, key(i.midpoint()))))
        .collect();
    assert_eq!(gmsh.interfaces.len(), grid.interfaces.len());
    assert_eq!(
        gmsh.interfaces.iter().filter(|i| i.b == GROUND).count(),
        8,
        "the clamp group: 8 ground springs"
    );
    for i in &gmsh.interfaces {
        let b = if i.b == GROUND {
            GROUND
        } else {
            map[i.b as usize] as u32
        };
        let (len, kn, ks, mid) = springs[&pair(map[i.a as usize] as u32, b)];
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-10 * y.abs();
        assert!(
            close(i.length, len)
                && close(i.k_n, kn)
                && close(i.k_s, ks)
                && key(i.midpoint()) == mid
        );
    }
    // The same loads on the tip.
    let loads = |m: &Model, map: &dyn Fn(u32) -> usize| {
        let mut l: Vec<_> = m
            .loads
            .iter()
            .map(|l| ((map(l.element), key(l.point)), l.force))
            .collect();
        l.sort_by_key(|x| x.0);
        l
    };
    let (a, b) = (
        loads(&gmsh, &|e| map[e as usize]),
        loads(&grid, &|e| e as usize),
    );
    assert_eq!(a.len(), 8);
    assert_eq!(
        a.iter().map(|x| x.0).collect::<Vec<_>>(),
        b.iter().map(|x| x.0).collect::<Vec<_>>()
    );
    for (x, y) in a.iter().zip(&b) {
        assert!(
            (x.1 - y.1).norm() <= 1e-10 * y.1.norm(),
            "{} vs {}",
            x.1,
            y.1
        );
    }
}

fn write(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn error_for(path: &std::path::Path, edge: &str) -> String {
    let json = format!(
        r#"{{"name": "g", "thickness": 1.0, "formulation": {{"kind": "rigid"}},
            "materials": {{"m": {{"E": 1e9, "nu": 0.2, "rho": 1000}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {{"kind": "gmsh", "path": {:?}}},
                         "supports": [{{"edge": "{edge}", "kind": "ground-spring"}}]}}],
            "time": {{"dt_factor": 0.5, "steps": 1}}}}"#,
        path.display().to_string()
    );
    let scene = Scene::from_json(&json).unwrap();
    Model::build(&scene).map(|_| ()).unwrap_err().to_string()
}

/// One second-order triangle (6 nodes), which a rigid-body-spring model cannot use.
const TRI6: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 6 1 6\n2 1 0 6\n1\n2\n3\n4\n5\n6\n\
0 0 0\n1 0 0\n0 1 0\n0.5 0 0\n0.5 0.5 0\n0 0.5 0\n$EndNodes\n$Elements\n1 1 1 1\n2 1 9 1\n1 1 2 3 4 5 6\n$EndElements\n";

#[test]
fn unsupported_files_and_names_are_refused_clearly() {
    let tmp = tempfile::tempdir().unwrap();
    let old = write(
        tmp.path(),
        "old.msh",
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n",
    );
    let e = error_for(&old, "left");
    assert!(
        e.contains("MSH version 2.2 is not supported") && e.contains("4.1"),
        "{e}"
    );
    let e = error_for(&write(tmp.path(), "tri6.msh", TRI6), "left");
    assert!(
        e.contains("Tri6") && e.contains("not supported") && e.contains("element 1"),
        "{e}"
    );
    let e = error_for(&write(tmp.path(), "junk.msh", "hello"), "left");
    assert!(
        e.contains("not a gmsh MSH file") && e.contains("`bodies[0].mesh.path`: "),
        "{e}"
    );
    // A data size the MSH reader panicked on (found by fuzzing), and a header cut short.
    let e = error_for(
        &write(
            tmp.path(),
            "size.msh",
            "$MeshFormat\n4.1 0 4294967296\n$EndMeshFormat\n",
        ),
        "left",
    );
    assert!(
        e.contains("4.1 0 4294967296") && e.contains("data size 8"),
        "{e}"
    );
    let e = error_for(
        &write(
            tmp.path(),
            "short.msh",
            "$MeshFormat\n4.1\n$EndMeshFormat\n",
        ),
        "left",
    );
    assert!(e.contains("file type 0"), "{e}");
    let msh = format!(
        "{}/examples/meshes/cantilever.msh",
        env!("CARGO_MANIFEST_DIR")
    );
    let e = error_for(std::path::Path::new(&msh), "clmap");
    assert!(e.contains("clmap") && e.contains("clamp, tip"), "{e}");
    let missing = Scene::from_json(
        r#"{"name": "g", "thickness": 1.0, "formulation": {"kind": "rigid"}, "materials": {"m": {"E": 1e9, "nu": 0.2, "rho": 1000}},
            "bodies": [{"name": "b", "material": "m", "mesh": {"kind": "gmsh", "path": "nowhere.msh"}}], "time": {"dt": 1e-6, "steps": 1}}"#,
    )
    .unwrap_err()
    .to_string();
    assert!(
        missing.contains("bodies[0].mesh.path") && missing.contains("nowhere.msh"),
        "{missing}"
    );
}

/// A `.geo` with physical curves but no `Physical Surface` makes gmsh save the curves alone:
/// the error says to add the surface, not to mesh in 2D.
#[test]
fn a_mesh_saved_without_its_physical_surface_is_explained() {
    let root = env!("CARGO_MANIFEST_DIR");
    let text = std::fs::read_to_string(format!("{root}/examples/meshes/cantilever.msh")).unwrap();
    // Drop the block of 640 quadrilaterals (entity 2 1, type 3); 16 boundary lines remain.
    let lines: Vec<&str> = text.lines().collect();
    let at = lines.iter().position(|l| l.trim() == "2 1 3 640").unwrap();
    let mut kept: Vec<&str> = lines[..at]
        .iter()
        .chain(&lines[at + 641..])
        .copied()
        .collect();
    let header = kept.iter().position(|l| *l == "$Elements").unwrap() + 1;
    kept[header] = "2 16 1 16";
    let dir = tempfile::tempdir().unwrap();
    let msh = dir.path().join("curves_only.msh");
    std::fs::write(&msh, kept.join("\n") + "\n").unwrap();
    let scene =
        std::fs::read_to_string(format!("{root}/examples/scenes/cantilever_gmsh.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&scene).unwrap();
    v["bodies"][0]["mesh"]["path"] = msh.to_string_lossy().into_owned().into();
    let e = rbsm::input::scene::Scene::from_json(&v.to_string())
        .and_then(|s| rbsm::model::Model::build(&s))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("Physical Surface") && !e.contains("gmsh -2"),
        "{e}"
    );
}
