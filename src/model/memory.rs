//! The memory a model needs, estimated from its scene before the model is built, against what
//! the process may still take: a model that does not fit is refused with both figures instead
//! of aborting when an allocation fails.

use crate::error::{Error, Result};
use crate::input::scene::{FormulationSpec, Scene};

/// Bytes per element a run holds at its peak, measured with `/usr/bin/time -f %M` on square
/// grids of 4·10⁴ and 3.6·10⁵ elements (`rbsm run --steps 2`: model, evaluator, Lanczos for
/// `Δt_crit`, integrator): at most 2.3 kB rigid and 5.0 kB hybrid, rounded up.
const RIGID_ELEMENT: u64 = 2_600;
const HYBRID_ELEMENT: u64 = 5_600;
/// Contact (vertices, edges, neighbour lists) multiplies that by at most this much, and each
/// body adds its own mesh (a wall of 3·10⁴ one-brick bodies: 4.0 to 4.5 kB per body).
const CONTACT_FACTOR: f64 = 1.5;
const PER_BODY: u64 = 1_500;
/// What the process holds before the model: code, thread stacks, allocator arenas.
const BASELINE: u64 = 256 << 20;

/// The estimated peak bytes of a run of `scene` with `elements` elements in all.
pub fn estimate(scene: &Scene, elements: u64) -> u64 {
    let per_element = match scene.formulation {
        FormulationSpec::Hybrid { .. } => HYBRID_ELEMENT,
        _ => RIGID_ELEMENT,
    };
    let factor = if scene.contact.is_some() {
        CONTACT_FACTOR
    } else {
        1.0
    };
    BASELINE
        + (elements as f64 * per_element as f64 * factor) as u64
        + scene.bodies.len() as u64 * PER_BODY
}

/// Refuses `scene` when a model of `elements` elements needs more memory than the process may
/// still take (see [`available`]).
pub fn ensure_fits(scene: &Scene, elements: u64) -> Result<()> {
    let need = estimate(scene, elements);
    match available() {
        Some(free) if need > free => Err(Error::scene("bodies", format!(
            "a model of {elements} elements needs about {} to run, and {} is available \
             (the least of the free memory, the address-space limit and the cgroup limit); use fewer or larger cells",
            gib(need), gib(free)))),
        _ => Ok(()),
    }
}

fn gib(bytes: u64) -> String {
    format!("{:.2} GiB", bytes as f64 / (1u64 << 30) as f64)
}

/// The bytes the process may still allocate: the least of the system's available memory
/// (`MemAvailable`), the room left under the address-space limit (`ulimit -v`) and under the
/// cgroup's memory limit. `None` where none of them can be read (not Linux).
pub fn available() -> Option<u64> {
    let read = |path: &str| std::fs::read_to_string(path).ok();
    let field = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line[key.len()..].split_whitespace().next()?.parse().ok()
    };
    let mut limits = Vec::new();
    if let Some(kb) = read("/proc/meminfo").and_then(|t| field(&t, "MemAvailable:")) {
        limits.push(kb * 1024);
    }
    let used_virtual = read("/proc/self/status")
        .and_then(|t| field(&t, "VmSize:"))
        .map(|kb| kb * 1024);
    if let (Some(limit), Some(used)) = (
        read("/proc/self/limits").and_then(|t| field(&t, "Max address space")),
        used_virtual,
    ) {
        limits.push(limit.saturating_sub(used));
    }
    let cgroup = |name: &str| {
        read(&format!("/sys/fs/cgroup/{name}")).and_then(|t| t.trim().parse::<u64>().ok())
    };
    if let (Some(max), Some(current)) = (cgroup("memory.max"), cgroup("memory.current")) {
        limits.push(max.saturating_sub(current));
    }
    limits.into_iter().min()
}
