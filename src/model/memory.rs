//! The memory a model needs, estimated from its scene before the model is built, against what
//! the process may still take: a model that does not fit is refused with both figures instead
//! of aborting when an allocation fails. The estimate is of address space (`VmPeak`), which
//! `ulimit -v` bounds and which bounds the resident memory; checked on `beam_drop.json` copied
//! 48 times and run to its end (1,488 interfaces released): 78 MB at the peak, 141 MB
//! estimated.

use crate::error::{Error, Result};
use crate::input::scene::{
    ContactModel, ElementStrengthSpec, EvaluatorKind, FormulationSpec, InterfaceLawSpec, Scene,
};

/// Address space per element at a run's peak (`VmPeak`, which bounds the resident `%M` of
/// `/usr/bin/time`), measured on Voronoi bars (`tension_bar.json`, three interfaces per element,
/// more than a grid's two) of 2·10⁴ and 10⁵ elements, `rbsm run --steps 2` (model, evaluator,
/// Lanczos for `Δt_crit`, integrator, outputs) on 2 threads with one malloc arena: the slope
/// between the two sizes, rounded up by about a tenth. Rigid and hybrid, by evaluator:
/// element-wise 3.24 and 4.09 kB (resident 2.81 and 3.52 kB), assembled 4.78 and 12.4 kB
/// (resident 3.2 and 7.2 kB: the sparse `K` is built in vectors that grow by doubling).
const ELEMENT_WISE: [u64; 2] = [3_600, 4_500];
const ASSEMBLED: [u64; 2] = [5_300, 13_700];
/// Failing interfaces (`mohr-coulomb`, `softening`) add their state per Gauss point: 1.67 kB
/// rigid, 2.44 kB hybrid (element-wise; resident 1.07 and 1.74 kB). Measured again the same way
/// with the screens and the inline return mapping (rigid, element-wise): slopes of 2.93 kB
/// failing and 2.65 kB elastic, the failing state now lying under the set-up's own peak; the
/// constants are kept, on the safe side.
const FAILING: [u64; 2] = [1_900, 2_700];
/// Elements that yield (`materials.*.element`, hybrid) keep a copy of `D`, `t A` and the
/// strength (120 bytes), the plastic strain and its flag (25 bytes): counted from the
/// structures' sizes, rounded up, not measured as the others were.
const YIELDING: u64 = 200;
/// The `rigid-poisson` correction (each cell's facets' coefficients, element-wise; `G` and
/// `t Gᵀ`, assembled; and their triplets while built), measured as above on Voronoi panels of
/// 2·10⁴ and 10⁵ elements against the same panels of rigid cells: element-wise slopes of 4.70
/// and 2.74 kB, 1.96 kB more; assembled within that (VmPeak 133.9 against 89.4 MB, 459.4
/// against 443.7 MB). Rounded up.
const POISSON: u64 = 2_500;
/// A body that fragments (failing interfaces and edge-to-edge contact, `Model::fragments`)
/// makes every element a contact target and every edge a source, with room for the neighbour
/// lists and pieces of all of them: 3.35 kB rigid, 3.80 kB hybrid more than the same body
/// without contact (resident 1.76 and 2.34 kB until it cracks).
const FRAGMENTS: u64 = 4_200;
/// Other contact (vertices, edges, neighbour lists) multiplies a body's elements' bytes by at
/// most this much, and each body adds its own mesh (a wall of 3·10⁴ one-brick bodies: 4.0 to
/// 4.5 kB per body).
const CONTACT_FACTOR: f64 = 1.5;
const PER_BODY: u64 = 1_500;
/// What the process holds before the model: code, the main thread's stack, the allocator's
/// first heap (8 to 10 MB measured, rounded up widely).
const BASELINE: u64 = 64 << 20;
/// Per thread of the pool: its stack (2 MiB, Rust's default, and a guard page).
const THREAD_STACK: u64 = (2 << 20) + 4096;
/// Per glibc malloc arena beyond the first: the 64 MiB of address space it reserves.
const ARENA: u64 = 64 << 20;

/// The malloc arenas the process was bounded to (`rbsm` bounds glibc's to one), 0 when not
/// bounded: then each thread may reserve an arena of its own.
static ARENAS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Tells the estimate that the process keeps at most `n` malloc arenas (glibc's `M_ARENA_MAX`).
pub fn arenas_bounded(n: usize) {
    ARENAS.store(n, std::sync::atomic::Ordering::Relaxed);
}

/// The estimated peak address space of a run of `scene` with `elements` elements in all,
/// `threads` threads in its pool: the process's, its threads' and each body's elements' (their
/// cells, as their meshes announce them; the elements of a gmsh body, unknown before it is read,
/// count at the largest bytes per element of the scene's bodies). It bounds the resident memory too: the
/// room reserved for fragments is touched as the bodies crack.
pub fn estimate(scene: &Scene, elements: u64, threads: usize) -> u64 {
    let hybrid = matches!(scene.formulation, FormulationSpec::Hybrid { .. }) as usize;
    let poisson = scene.formulation == FormulationSpec::RigidPoisson;
    let base = match scene.evaluator {
        EvaluatorKind::Assembled => ASSEMBLED[hybrid],
        EvaluatorKind::ElementWise => ELEMENT_WISE[hybrid],
    };
    let edge_to_edge = scene
        .contact
        .is_some_and(|c| c.model == ContactModel::EdgeToEdge);
    let per_body: Vec<(u64, f64)> = scene
        .bodies
        .iter()
        .map(|b| {
            let material = scene.materials.get(&b.material);
            let fails = material.is_some_and(|m| m.interface != InterfaceLawSpec::Elastic);
            let yields = material.is_some_and(|m| m.element != ElementStrengthSpec::Elastic);
            let bytes = base
                + if fails { FAILING[hybrid] } else { 0 }
                + if yields { YIELDING } else { 0 }
                + if poisson { POISSON } else { 0 };
            let bytes = match (scene.contact.is_some(), fails && edge_to_edge) {
                (_, true) => (bytes + FRAGMENTS) as f64,
                (true, false) => bytes as f64 * CONTACT_FACTOR,
                (false, false) => bytes as f64,
            };
            (crate::mesh::cells_of(&b.mesh).unwrap_or(0), bytes)
        })
        .collect();
    let known: u64 = per_body.iter().map(|(n, _)| n).sum();
    let largest = per_body.iter().map(|p| p.1).fold(0.0, f64::max);
    // Each body's bytes per element, weighted by its cells; the elements the meshes did not
    // announce (gmsh bodies, counted once read) at the largest.
    let weighted = per_body.iter().map(|&(n, b)| n as f64 * b).sum::<f64>()
        + elements.saturating_sub(known) as f64 * largest;
    BASELINE + reserved(threads) + weighted as u64 + scene.bodies.len() as u64 * PER_BODY
}

/// The part of [`estimate`] that is address space reserved and mostly never touched: the
/// threads' stacks and the malloc arenas beyond the first (each thread's own unless the
/// process bounded them). It counts against `ulimit -v`, not against the free memory.
fn reserved(threads: usize) -> u64 {
    let arenas = match ARENAS.load(std::sync::atomic::Ordering::Relaxed) {
        0 => threads as u64,
        n => n as u64 - 1,
    };
    threads as u64 * THREAD_STACK + arenas * ARENA
}

/// Refuses `scene` when a model of `elements` elements needs more address space than is left
/// under `ulimit -v`, or more memory (the estimate without `reserved`) than is free or left
/// under the cgroup's limit (see `room`), with the two figures that do not fit.
///
/// # Errors
/// The estimate for `elements` is more than the room left under `ulimit -v`, or, without the
/// reserved address space, more than the free memory or the room under the cgroup's limit. Never
/// where neither can be read (not Linux).
pub fn ensure_fits(scene: &Scene, elements: u64) -> Result<()> {
    let threads = rayon::current_num_threads();
    let need = estimate(scene, elements, threads);
    let touched = need - reserved(threads);
    let (memory, address) = room();
    let short = match (address, memory) {
        (Some(free), _) if need > free => Some((
            need,
            free,
            "the room left under the address-space limit, `ulimit -v`",
        )),
        (_, Some(free)) if touched > free => Some((
            touched,
            free,
            "the least of the free memory and the room left under the cgroup's limit",
        )),
        _ => None,
    };
    match short {
        Some((need, free, what)) => Err(Error::scene(
            "bodies",
            format!(
                "a model of {elements} elements needs about {} to run, and {} is available \
                 ({what}); use fewer or larger cells",
                gib(need),
                gib(free)
            ),
        )),
        None => Ok(()),
    }
}

fn gib(bytes: u64) -> String {
    format!("{:.2} GiB", bytes as f64 / (1u64 << 30) as f64)
}

/// The bytes the process may still allocate: the least of `room`'s two figures. `None`
/// where none of them can be read (not Linux).
pub fn available() -> Option<u64> {
    let (memory, address) = room();
    memory.into_iter().chain(address).min()
}

/// What the process may still take: the memory, the least of the system's available memory
/// (`MemAvailable`) and the room left under the cgroup's memory limit; and the address space,
/// the room left under `ulimit -v`. Each `None` where it cannot be read (not Linux, no limit).
fn room() -> (Option<u64>, Option<u64>) {
    let read = |path: &str| std::fs::read_to_string(path).ok();
    let field = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line[key.len()..].split_whitespace().next()?.parse().ok()
    };
    let mut memory = Vec::new();
    if let Some(kb) = read("/proc/meminfo").and_then(|t| field(&t, "MemAvailable:")) {
        memory.push(kb * 1024);
    }
    let cgroup = |name: &str| {
        read(&format!("/sys/fs/cgroup/{name}")).and_then(|t| t.trim().parse::<u64>().ok())
    };
    if let (Some(max), Some(current)) = (cgroup("memory.max"), cgroup("memory.current")) {
        memory.push(max.saturating_sub(current));
    }
    let used_virtual = read("/proc/self/status")
        .and_then(|t| field(&t, "VmSize:"))
        .map(|kb| kb * 1024);
    let address = match (
        read("/proc/self/limits").and_then(|t| field(&t, "Max address space")),
        used_virtual,
    ) {
        (Some(limit), Some(used)) => Some(limit.saturating_sub(used)),
        _ => None,
    };
    (memory.into_iter().min(), address)
}
