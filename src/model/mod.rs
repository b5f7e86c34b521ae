//! The model: elements, interfaces (with the springs of eq. 12), supports, loads and initial
//! motion. Built once from a scene, immutable afterwards; every analysis reads this one copy.

pub mod checks;
pub mod facet;
pub mod formulation;
pub mod law;
pub mod loads;
pub mod mass;
pub mod memory;
pub mod plasticity;
pub mod poisson;

use crate::error::{Error, Result};
use crate::input::scene::{BodySpec, EdgeSet, Side};
use crate::input::scene::{
    ClampSpec, Component, ContactSpec, ForceSpec, GroundSpringSpec, LoadSpec, MaterialSpec, Plane,
    Scene, SupportSpec, TractionSpec,
};
use crate::mesh::geometry::{area_properties, AreaProperties, Vec2};
use crate::mesh::Mesh;
use crate::model::formulation::{elasticity, Formulation};
use crate::model::law::{Elastic, InterfaceLaw};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Marks the `b` side of an interface tied to fixed ground (`U_b = 0`, `h_b = 0`).
pub const GROUND: u32 = u32::MAX;

/// A rigid polygonal element.
#[derive(Debug, Clone)]
pub struct Element {
    /// Index of the body it belongs to.
    pub body: u32,
    /// Area, centroid (the reference point `x_e`) and central second moments.
    pub props: AreaProperties,
    /// Density (kg/m³).
    pub rho: f64,
    /// Elasticity matrix `D` (Pa) of its material, plane stress or strain (hybrid interior term).
    pub d: nalgebra::Matrix3<f64>,
    /// The strength of its constant stress, when its material gives one (hybrid only).
    pub strength: Option<plasticity::ElementStrength>,
}

/// A shared edge carrying normal and shear penalty springs (eqs. 6, 11, 12).
#[derive(Debug, Clone, Copy)]
pub struct Interface {
    /// The first element; the normal points away from it.
    pub a: u32,
    /// The other element, or [`GROUND`].
    pub b: u32,
    /// End points of the edge (m).
    pub p1: Vec2,
    /// Second end point (m); `p1 → p2` runs counter-clockwise around `a`.
    pub p2: Vec2,
    /// Unit normal from `a` to `b`.
    pub normal: Vec2,
    /// Unit tangent, `normal = ẑ × tangent`.
    pub tangent: Vec2,
    /// Edge length `L` (m).
    pub length: f64,
    /// Perpendicular distances from the centroids to the edge line (m).
    pub h_a: f64,
    /// Distance from `b`'s centroid (m); 0 for ground.
    pub h_b: f64,
    /// Spring constants per unit edge length and thickness (Pa/m): eq. 12, times the penalty
    /// `p` for the hybrid formulation.
    pub k_n: f64,
    /// Shear spring `k_s` (Pa/m).
    pub k_s: f64,
    /// Its law (eq. 11): an index in [`Model::laws`], or [`DEFAULT_LAW`] for the model's
    /// [`Model::law`] ([`Model::law_of`]).
    pub law: u32,
}

/// [`Interface::law`] of an interface under the model's default law.
pub const DEFAULT_LAW: u32 = u32::MAX;

impl Interface {
    /// The two Gauss points of the edge and their weight (`L/2` each): exact for the quadratic
    /// integrand of the interface energy (the crate documentation's *Assembled form*).
    pub fn gauss_points(&self) -> ([Vec2; 2], f64) {
        let m = 0.5 * (self.p1 + self.p2);
        let half = 0.5 * (self.p2 - self.p1) / 3f64.sqrt();
        ([m - half, m + half], 0.5 * self.length)
    }

    /// The distance `h = L/(2√3)` of each Gauss point from the midpoint.
    pub fn gauss_offset(&self) -> f64 {
        self.length / (2.0 * 3f64.sqrt())
    }

    /// The midpoint of the edge.
    pub fn midpoint(&self) -> Vec2 {
        0.5 * (self.p1 + self.p2)
    }
}

/// A load in time: piecewise-linear amplitude `[t, factor]`, held constant outside its range.
#[derive(Debug, Clone, PartialEq)]
pub struct Amplitude(pub Vec<[f64; 2]>);

impl Amplitude {
    /// The factor at time `t`.
    pub fn at(&self, t: f64) -> f64 {
        let p = &self.0;
        if t <= p[0][0] {
            return p[0][1];
        }
        match p.iter().position(|q| q[0] > t) {
            None => p[p.len() - 1][1],
            Some(k) => {
                let (a, b) = (p[k - 1], p[k]);
                a[1] + (b[1] - a[1]) * (t - a[0]) / (b[0] - a[0])
            }
        }
    }
}

/// A point force and moment on an element.
#[derive(Debug, Clone)]
pub struct Load {
    /// The element it acts on (global index).
    pub element: u32,
    /// Where the force acts (m).
    pub point: Vec2,
    /// Force (N) and moment (N·m).
    pub force: Vec2,
    /// Moment (N·m).
    pub moment: f64,
    /// Time variation; `None` is constant.
    pub amplitude: Option<Amplitude>,
}

/// A meshed body.
#[derive(Debug, Clone)]
pub struct Body {
    /// The body's name in the scene.
    pub name: String,
    /// The body's mesh, placed (origin and initial rotation applied).
    pub mesh: Mesh,
    /// Its elements are `first_element .. first_element + mesh.n_cells()`.
    pub first_element: usize,
    /// The numerators `E_n`, `E_s` (Pa) of its springs, `k = E / (h_a + h_b)` (eq. 12).
    pub moduli: [f64; 2],
    /// The interfaces of its shared edges are `first_interface ..` in `mesh.shared` order.
    pub first_interface: usize,
}

/// Everything the evaluators, the integrator and the analyses need.
#[derive(Debug, Clone)]
pub struct Model {
    /// The scene's name.
    pub name: String,
    /// Plane stress or plane strain.
    pub plane: Plane,
    /// Thickness `t` (m).
    pub thickness: f64,
    /// Rigid or hybrid (eq. 5).
    pub formulation: Formulation,
    /// The meshed bodies, in scene order.
    pub bodies: Vec<Body>,
    /// Every element of every body, body after body.
    pub elements: Vec<Element>,
    /// Interfaces between elements, then ground springs.
    pub interfaces: Vec<Interface>,
    /// Fixed DOFs (global indices, sorted).
    pub fixed: Vec<usize>,
    /// Point loads: each traction becomes one force per boundary edge, at its midpoint.
    pub loads: Vec<Load>,
    /// Gravitational acceleration (m/s²), zero when the scene has none.
    pub gravity: Vec2,
    /// Mass-proportional damping `α` (1/s).
    pub damping: f64,
    /// Local non-viscous damping `α` in [0, 1) (the step stage's `local` module); 0 for none.
    pub local_damping: f64,
    /// The unbalanced-force ratio below which a run stops (`time.stop_ratio`), if any.
    pub stop_ratio: Option<f64>,
    /// Initial velocity of every DOF (`ndof` per element).
    pub initial_velocity: Vec<f64>,
    /// Contact between bodies and with the ground; `None` when the scene has none.
    pub contact: Option<ContactSpec>,
    /// Rigid ground segments `[from, to]` (m); the free side is on the left of `from → to`.
    pub ground: Vec<[Vec2; 2]>,
    /// The default law (eq. 11): that of the contact springs, the supports and the interfaces of
    /// materials with no law of their own; [`Elastic`] unless replaced.
    pub law: Arc<dyn InterfaceLaw>,
    /// The laws of their own of the materials that have one (`materials.*.interface` other
    /// than `elastic`), one per such material in name order; [`Interface::law`] indexes them.
    pub laws: Vec<Arc<dyn InterfaceLaw>>,
    /// Clamps that move (displacement control), in scene order.
    pub prescribed: Vec<Prescribed>,
}

/// A clamp that moves at a given velocity (displacement control): its elements' clamped `u`
/// and `v` follow `d(t)`, the velocity rising linearly over the ramp.
#[derive(Debug, Clone)]
pub struct Prescribed {
    /// `<body>_s<k>`: the body's name and the support's index, the prefix of its history
    /// columns.
    pub name: String,
    /// The velocity after the ramp (m/s).
    pub velocity: Vec2,
    /// The ramp's duration (s).
    pub ramp: f64,
    /// The moving DOFs (global indices) with the velocity component each follows (0: x, 1: y).
    pub dofs: Vec<(usize, usize)>,
}

impl Prescribed {
    /// The displacement `d(t)` along the velocity's direction per unit speed: `t²/(2 T)` during
    /// the ramp `T`, then `t − T/2`.
    pub fn travel(&self, t: f64) -> f64 {
        if t < self.ramp {
            0.5 * t * t / self.ramp
        } else {
            t - 0.5 * self.ramp
        }
    }

    /// The displacement of component `c` at time `t` (m).
    pub fn displacement(&self, c: usize, t: f64) -> f64 {
        self.velocity[c] * self.travel(t)
    }
}

impl Model {
    /// Whether body `bi` breaks into fragments: its interfaces can fail and the scene has
    /// edge-to-edge contact, so that a broken interface whose elements have moved apart is
    /// handed over to contact (`force::failure`, `force::contact`).
    pub fn fragments(&self, bi: usize) -> bool {
        let body = &self.bodies[bi];
        self.contact
            .is_some_and(|c| c.model == crate::input::scene::ContactModel::EdgeToEdge)
            && self.interfaces[body.first_interface..][..body.mesh.shared.len()]
                .iter()
                .any(|i| self.fails(i))
    }

    /// The law of interface `i` (eq. 11).
    pub fn law_of(&self, i: &Interface) -> &dyn InterfaceLaw {
        match i.law {
            DEFAULT_LAW => &*self.law,
            k => &*self.laws[k as usize],
        }
    }

    /// Whether interface `i` can fail: it joins two elements and its law is not linear, so its
    /// Gauss points have a state (supports keep their law's springs).
    pub fn fails(&self, i: &Interface) -> bool {
        i.b != GROUND && !self.law_of(i).is_linear()
    }

    /// Whether any interface can fail.
    pub fn any_fails(&self) -> bool {
        self.interfaces.iter().any(|i| self.fails(i))
    }

    /// Whether any element has a strength of its own (hybrid, [`plasticity`]).
    pub fn any_yields(&self) -> bool {
        self.elements.iter().any(|e| e.strength.is_some())
    }

    /// The interfaces that can fail (indices in [`Model::interfaces`]) in the order of the
    /// evaluators' sweep: by their lower element, then their higher one, then their index. The
    /// state of their Gauss points is kept in this order (`force::failure`), so that a sweep
    /// meets it in turn.
    pub fn failing_interfaces(&self) -> Vec<u32> {
        let mut failing: Vec<u32> = (0..self.interfaces.len() as u32)
            .filter(|&k| self.fails(&self.interfaces[k as usize]))
            .collect();
        failing.sort_by_key(|&k| {
            let i = &self.interfaces[k as usize];
            (i.a.min(i.b), i.a.max(i.b), k)
        });
        failing
    }

    /// Gives the interfaces between elements for which `which` holds the law `law` (a law the
    /// scene cannot name: the seam of eq. 11 from code). Supports keep theirs.
    pub fn set_law(&mut self, law: Arc<dyn InterfaceLaw>, which: impl Fn(&Interface) -> bool) {
        let k = self.laws.len() as u32;
        self.laws.push(law);
        for i in self.interfaces.iter_mut().filter(|i| i.b != GROUND) {
            if which(i) {
                i.law = k;
            }
        }
    }

    /// Number of ground springs: the interfaces tied to ground (`b == GROUND`). The others
    /// are the interfaces between elements.
    pub fn ground_springs(&self) -> usize {
        self.interfaces.iter().filter(|i| i.b == GROUND).count()
    }
}

/// The elements found at points ([`Model::elements_at`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Located {
    /// The element (global index) containing each point, `None` for a point in none.
    pub elements: Vec<Option<usize>>,
    /// Point-in-polygon tests made: about one per point when the points are spread over the
    /// elements (a search that tried every element for every point made their product).
    pub tests: u64,
}

/// Whether the polygon `cell` holds `x`, inside or on its boundary (within 1e-12 of an edge's
/// length of the edge).
fn cell_holds(cell: &[Vec2], x: Vec2) -> bool {
    let n = cell.len();
    (0..n).any(|i| {
        let (a, b) = (cell[i], cell[(i + 1) % n]);
        crate::mesh::geometry::point_segment_distance(x, a, b) <= 1e-12 * (a - b).norm()
    }) || crate::mesh::geometry::point_in_polygon(x, cell)
}

/// The numerators of eq. 12, `k_n = E_n / (h_a + h_b)`, `k_s = E_s / (h_a + h_b)`:
/// `E_n = E/(1 − ν²)`, `E_s = E/(1 + ν)`; plane strain uses `E' = E/(1 − ν²)` and
/// `ν' = ν/(1 − ν)` in the same formulas. The `rigid-poisson` formulation takes both as
/// `2μ = E/(1 + ν)` in either plane: the springs of a lattice of `ν = 0`, which its correction
/// completes ([`poisson`]).
pub fn spring_moduli(m: &MaterialSpec, plane: Plane, formulation: Formulation) -> [f64; 2] {
    if formulation == Formulation::RigidPoisson {
        return [m.e / (1.0 + m.nu); 2];
    }
    let (e, nu) = match plane {
        Plane::Stress => (m.e, m.nu),
        Plane::Strain => (m.e / (1.0 - m.nu * m.nu), m.nu / (1.0 - m.nu)),
    };
    [e / (1.0 - nu * nu), e / (1.0 + nu)]
}

impl Model {
    /// Builds the model of a validated scene ([`Scene::validate`]): per body its mesh, elements,
    /// interfaces, supports and loads, in scene order.
    ///
    /// # Errors
    /// A mesh that cannot be built or has a degenerate element or edge, a model that would not
    /// fit in memory, an edge, span, element, DOF or probe of the scene that names nothing in
    /// its mesh, or masses and springs that are not finite.
    pub fn build(scene: &Scene) -> Result<Model> {
        let formulation = Formulation::from_spec(scene.formulation)?;
        let t = scene.thickness;
        let mut model = Model {
            name: scene.name.clone(),
            plane: scene.plane,
            thickness: t,
            formulation,
            bodies: Vec::new(),
            elements: Vec::new(),
            interfaces: Vec::new(),
            fixed: Vec::new(),
            loads: Vec::new(),
            gravity: scene
                .gravity
                .map(|g| Vec2::new(g[0], g[1]))
                .unwrap_or_else(Vec2::zeros),
            damping: scene.damping.unwrap_or(0.0),
            local_damping: scene.local_damping.unwrap_or(0.0),
            stop_ratio: scene.time.stop_ratio,
            initial_velocity: Vec::new(),
            contact: scene.contact,
            ground: scene
                .ground
                .iter()
                .map(|g| [Vec2::new(g.from[0], g.from[1]), Vec2::new(g.to[0], g.to[1])])
                .collect(),
            law: Arc::new(Elastic),
            laws: Vec::new(),
            prescribed: Vec::new(),
        };
        // One law per material that has its own, in name order.
        let mut own_law = BTreeMap::new();
        for (name, m) in &scene.materials {
            if let Some(law) = interface_law(&m.interface) {
                own_law.insert(name.as_str(), model.laws.len() as u32);
                model.laws.push(law);
            }
        }
        // What the scene's meshes will make, known before meshing except for gmsh files,
        // whose elements are counted once read.
        let mut expected: u64 = scene
            .bodies
            .iter()
            .filter_map(|b| crate::mesh::cells_of(&b.mesh))
            .sum();
        memory::ensure_fits(scene, expected)?;
        for (bi, spec) in scene.bodies.iter().enumerate() {
            let material = scene.materials[&spec.material];
            if let crate::input::scene::MeshSpec::Voronoi(v) = &spec.mesh {
                if let Some(domain) = &v.domain {
                    let point = |p: &[f64; 2]| Vec2::new(p[0], p[1]);
                    let outline: Vec<Vec2> = domain.outline(v.sites).iter().map(point).collect();
                    crate::mesh::voronoi::check_domain(&outline, point(&v.origin), point(&v.size))
                        .map_err(|m| Error::scene(format!("bodies[{bi}].mesh.domain"), m))?;
                }
            }
            let mut mesh = Mesh::from_spec(&spec.name, &format!("bodies[{bi}].mesh"), &spec.mesh)?;
            if crate::mesh::cells_of(&spec.mesh).is_none() {
                expected += mesh.n_cells() as u64;
                memory::ensure_fits(scene, expected)?;
            }
            let first = model.add_elements(bi, spec, &material, &mut mesh, scene.plane);
            let first_interface = model.interfaces.len();
            let law = own_law
                .get(spec.material.as_str())
                .copied()
                .unwrap_or(DEFAULT_LAW);
            for e in &mesh.shared {
                let iface = model
                    .interface(
                        first + e.a as usize,
                        Some(first + e.b as usize),
                        &mesh,
                        e.v1,
                        e.v2,
                        &material,
                    )
                    .map_err(|m| Error::mesh(&spec.name, e.a as usize, m))?;
                model.interfaces.push(Interface { law, ..iface });
            }
            model.add_supports(bi, spec, &mesh, &material, first)?;
            model.add_loads(bi, spec, &mesh, first)?;
            model.bodies.push(Body {
                name: spec.name.clone(),
                mesh,
                first_element: first,
                moduli: spring_moduli(&material, scene.plane, formulation),
                first_interface,
            });
        }
        model.check_finite(scene)?;
        model.fixed.sort_unstable();
        model.fixed.dedup();
        model.probe_elements(&scene.output.probes)?;
        for (k, p) in scene.output.probes.iter().enumerate() {
            dof_index(&p.dof, formulation, &format!("output.probes[{k}].dof"))?;
        }
        Ok(model)
    }

    /// The elements of body `bi` (`spec`, meshed as `mesh`, which it turns by the body's initial
    /// rotation) with their initial velocities; returns the index of the first.
    fn add_elements(
        &mut self,
        bi: usize,
        spec: &BodySpec,
        material: &MaterialSpec,
        mesh: &mut Mesh,
        plane: Plane,
    ) -> usize {
        let nd = self.formulation.ndof();
        let first = self.elements.len();
        let props: Vec<AreaProperties> = (0..mesh.n_cells())
            .map(|c| area_properties(&mesh.cell_points(c)))
            .collect();
        let body_area: f64 = props.iter().map(|p| p.area).sum();
        let body_centroid = props.iter().map(|p| p.area * p.centroid).sum::<Vec2>() / body_area;
        let rot = nalgebra::Rotation2::new(spec.initial.rotation_deg.to_radians());
        if spec.initial.rotation_deg != 0.0 {
            for v in &mut mesh.vertices {
                *v = body_centroid + rot * (*v - body_centroid);
            }
        }
        let omega = spec.initial.angular_velocity;
        let v0 = Vec2::new(spec.initial.velocity[0], spec.initial.velocity[1]);
        for c in 0..mesh.n_cells() {
            let p = area_properties(&mesh.cell_points(c));
            self.elements.push(Element {
                body: bi as u32,
                props: p,
                rho: material.rho,
                d: elasticity(material.e, material.nu, plane),
                strength: material
                    .element
                    .cohesion_friction()
                    .map(|(c, phi)| plasticity::ElementStrength::new(c, phi, plane)),
            });
            let r = p.centroid - body_centroid;
            let mut v = vec![0.0; nd];
            v[0] = v0.x - omega * r.y;
            v[1] = v0.y + omega * r.x;
            v[2] = omega;
            self.initial_velocity.extend(v);
        }
        first
    }

    /// The supports of body `bi` (`spec`, meshed as `mesh`, its elements from `first`): ground
    /// springs (interfaces to ground, with the default law) and clamps (fixed DOFs, and the
    /// moving ones of displacement control).
    fn add_supports(
        &mut self,
        bi: usize,
        spec: &BodySpec,
        mesh: &Mesh,
        material: &MaterialSpec,
        first: usize,
    ) -> Result<()> {
        let (nd, formulation) = (self.formulation.ndof(), self.formulation);
        let at = |k: &str| format!("bodies[{bi}].{k}");
        for (k, s) in spec.supports.iter().enumerate() {
            let field = at(&format!("supports[{k}].edge"));
            match s {
                SupportSpec::GroundSpring(GroundSpringSpec {
                    edge,
                    components,
                    span,
                }) => {
                    let span_field = at(&format!("supports[{k}].span"));
                    for (e, [p1, p2]) in
                        supported_edges(mesh, edge, span, true, &field, &span_field)?
                    {
                        let mut iface = self
                            .interface(first + e.cell as usize, None, mesh, e.v1, e.v2, material)
                            .map_err(|m| Error::mesh(&spec.name, e.cell as usize, m))?;
                        // A span may hold part of an edge: a bearing strip on the same line.
                        (iface.p1, iface.p2, iface.length) = (p1, p2, (p2 - p1).norm());
                        if !components.contains(&Component::N) {
                            iface.k_n = 0.0;
                        }
                        if !components.contains(&Component::S) {
                            iface.k_s = 0.0;
                        }
                        // Supports are boundary conditions, not material: they keep the
                        // default law.
                        self.interfaces.push(iface);
                    }
                }
                SupportSpec::Clamp(ClampSpec {
                    edge,
                    dofs,
                    velocity,
                    ramp,
                    span,
                }) => {
                    let which: Vec<usize> = match dofs {
                        None => (0..nd).collect(),
                        Some(names) => names
                            .iter()
                            .map(|n| dof_index(n, formulation, &at(&format!("supports[{k}].dofs"))))
                            .collect::<Result<_>>()?,
                    };
                    let mut moving = Vec::new();
                    let span_field = at(&format!("supports[{k}].span"));
                    for (e, _) in supported_edges(mesh, edge, span, false, &field, &span_field)? {
                        let el = first + e.cell as usize;
                        self.fixed.extend(which.iter().map(|&d| el * nd + d));
                        moving.extend(which.iter().filter(|&&d| d < 2).map(|&d| (el * nd + d, d)));
                    }
                    if let Some(v) = velocity {
                        moving.sort_unstable();
                        moving.dedup();
                        self.prescribed.push(Prescribed {
                            name: format!("{}_s{k}", spec.name),
                            velocity: Vec2::new(v[0], v[1]),
                            ramp: *ramp,
                            dofs: moving,
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// The loads of body `bi`: each traction as one force per boundary edge at its midpoint,
    /// each force at its element's centroid.
    fn add_loads(&mut self, bi: usize, spec: &BodySpec, mesh: &Mesh, first: usize) -> Result<()> {
        let t = self.thickness;
        let at = |k: &str| format!("bodies[{bi}].{k}");
        for (k, l) in spec.loads.iter().enumerate() {
            match l {
                LoadSpec::Traction(TractionSpec {
                    edge,
                    value,
                    amplitude,
                }) => {
                    let q = Vec2::new(value[0], value[1]);
                    for e in side_edges(mesh, edge, &at(&format!("loads[{k}].edge")))? {
                        let (p, r) = (mesh.vertices[e.v1 as usize], mesh.vertices[e.v2 as usize]);
                        // Uniform traction: the resultant acts at the midpoint, exactly.
                        self.loads.push(Load {
                            element: (first + e.cell as usize) as u32,
                            point: 0.5 * (p + r),
                            force: q * (r - p).norm() * t,
                            moment: 0.0,
                            amplitude: amplitude.clone().map(Amplitude),
                        });
                    }
                }
                LoadSpec::Force(ForceSpec {
                    element,
                    value,
                    amplitude,
                }) => {
                    if *element >= mesh.n_cells() {
                        return Err(Error::scene(
                            at(&format!("loads[{k}].element")),
                            format!(
                                "must lie in 0..{} (elements of body `{}`), got {element}",
                                mesh.n_cells(),
                                spec.name
                            ),
                        ));
                    }
                    let el = first + element;
                    self.loads.push(Load {
                        element: el as u32,
                        point: self.elements[el].props.centroid,
                        force: Vec2::new(value[0], value[1]),
                        moment: value[2],
                        amplitude: amplitude.clone().map(Amplitude),
                    });
                }
            }
        }
        Ok(())
    }

    /// The interface on the edge `v1 → v2` of element `a` (counter-clockwise in `a`), to element
    /// `b` or to ground; `Err` explains a degenerate geometry.
    fn interface(
        &self,
        a: usize,
        b: Option<usize>,
        mesh: &Mesh,
        v1: u32,
        v2: u32,
        m: &MaterialSpec,
    ) -> std::result::Result<Interface, String> {
        let (p1, p2) = (mesh.vertices[v1 as usize], mesh.vertices[v2 as usize]);
        let length = (p2 - p1).norm();
        if length == 0.0 {
            return Err(format!("edge ({v1}, {v2}) has zero length"));
        }
        // Counter-clockwise in `a`: the outward normal is the edge direction turned clockwise.
        let dir = (p2 - p1) / length;
        let normal = Vec2::new(dir.y, -dir.x);
        let tangent = Vec2::new(normal.y, -normal.x);
        let h_a = (p1 - self.elements[a].props.centroid).dot(&normal).abs();
        let h_b = b.map_or(0.0, |b| {
            (self.elements[b].props.centroid - p1).dot(&normal).abs()
        });
        if !(h_a + h_b > 1e-12 * length) {
            return Err(format!(
                "edge ({v1}, {v2}): the centroids lie on the edge line (h_a + h_b = 0)"
            ));
        }
        let [e_n, e_s] = spring_moduli(m, self.plane, self.formulation);
        let (k_n, k_s) = [e_n, e_s]
            .map(|e| e / (h_a + h_b) * self.formulation.spring_factor())
            .into();
        Ok(Interface {
            a: a as u32,
            b: b.map_or(GROUND, |b| b as u32),
            p1,
            p2,
            normal,
            tangent,
            length,
            h_a,
            h_b,
            k_n,
            k_s,
            law: DEFAULT_LAW,
        })
    }

    /// Masses and spring constants must be finite numbers: extreme inputs (a thickness of
    /// 1e300, say) overflow, and the solvers would then compute with infinities.
    fn check_finite(&self, scene: &Scene) -> Result<()> {
        let t = self.thickness;
        for (e, el) in self.elements.iter().enumerate() {
            let m = el.rho * t * el.props.area;
            let nd = self.formulation.ndof();
            let massive = m.is_normal() && m > 0.0 && (m * el.props.polar()).is_normal();
            let block = nalgebra::DMatrix::from_row_slice(
                nd,
                nd,
                &self.formulation.mass(&el.props, el.rho * t),
            );
            if !massive || (block.clone().cholesky().is_none() && nd == 3) {
                return Err(Error::scene(scene.most_extreme(el.body as usize, &["rho", "thickness"]), format!(
                    "the mass of element {e} ({m:e} kg, rotational inertia {:e} kg m²) is not a positive normal number; \
                     check rho, thickness and the mesh size", m * el.props.polar())));
            }
            if block.cholesky().is_none() {
                let body = &self.bodies[el.body as usize];
                return Err(Error::mesh(
                    &body.name,
                    e - body.first_element,
                    "its consistent mass is not positive definite in double precision: \
                    the element is too elongated (extreme aspect ratio) for the hybrid formulation",
                ));
            }
        }
        for i in &self.interfaces {
            if !((i.k_n + i.k_s) * t * i.length * (1.0 + i.length * i.length)).is_finite() {
                return Err(Error::scene(
                    scene.most_extreme(
                        self.elements[i.a as usize].body as usize,
                        &["E", "thickness", "penalty"],
                    ),
                    format!(
                    "the springs between elements {} and {} overflow (k_n = {:e} Pa/m); check E, \
                        thickness, the penalty and the mesh size", i.a, i.b, i.k_n),
                ));
            }
        }
        Ok(())
    }

    /// The element (global index) containing the reference point `x`: the first whose polygon
    /// holds it, inside or on its boundary.
    pub fn element_at(&self, x: Vec2) -> Option<usize> {
        self.elements_at(&[x]).elements[0]
    }

    /// The element (global index) containing each reference point of `points`, as
    /// [`Model::element_at`] finds it. The points are filed in a bucket grid and each element
    /// is tested against the points near its box only, so that the search is linear in the
    /// number of elements and of points, not their product.
    pub fn elements_at(&self, points: &[Vec2]) -> Located {
        let mut found = Located {
            elements: vec![None; points.len()],
            tests: 0,
        };
        let Some(&first) = points.first() else {
            return found;
        };
        let (lo, hi) = points
            .iter()
            .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        let grid = crate::mesh::buckets::Buckets::new(lo, hi, points.len());
        let mut lists = crate::mesh::buckets::BucketLists::default();
        lists.fill(&grid, points.len(), |i| (points[i], points[i]));
        let mut left = points.len();
        let mut cell = Vec::new();
        for b in &self.bodies {
            for c in 0..b.mesh.n_cells() {
                cell.clear();
                cell.extend(b.mesh.cell(c).iter().map(|&v| b.mesh.vertices[v as usize]));
                let (clo, chi) = cell
                    .iter()
                    .fold((cell[0], cell[0]), |(l, h), p| (l.inf(p), h.sup(p)));
                // A point on an edge is in the cell within 1e-12 of the edge's length, so
                // within that of the box's diagonal.
                let tol = Vec2::repeat(2e-12 * (chi - clo).norm());
                let (clo, chi) = (clo - tol, chi + tol);
                if !crate::mesh::buckets::boxes_meet((clo, chi), (lo, hi)) {
                    continue;
                }
                for k in grid.touching(clo, chi) {
                    for &i in lists.bucket(k) {
                        let (i, x) = (i as usize, points[i as usize]);
                        if found.elements[i].is_some()
                            || !crate::mesh::buckets::boxes_meet((clo, chi), (x, x))
                        {
                            continue;
                        }
                        found.tests += 1;
                        if cell_holds(&cell, x) {
                            found.elements[i] = Some(b.first_element + c);
                            left -= 1;
                        }
                    }
                }
                if left == 0 {
                    return found;
                }
            }
        }
        found
    }

    /// The element of each probe of `probes` (`output.probes`): its `element`, checked, or the
    /// one containing its `at`, all found in one search ([`Model::elements_at`]).
    ///
    /// # Errors
    /// A probe's `at` lies in no element, or a probe without `at` has no `element` or one outside
    /// the model (`output.probes[k]`).
    pub fn probe_elements(&self, probes: &[crate::input::scene::ProbeSpec]) -> Result<Vec<usize>> {
        let points: Vec<Vec2> = probes
            .iter()
            .filter_map(|p| p.at.map(|[x, y]| Vec2::new(x, y)))
            .collect();
        let mut located = self.elements_at(&points).elements.into_iter();
        probes
            .iter()
            .enumerate()
            .map(|(k, p)| match (p.element, p.at) {
                (_, Some([x, y])) => located.next().flatten().ok_or_else(|| {
                    Error::scene(
                        format!("output.probes[{k}].at"),
                        format!(
                            "[{x}, {y}] lies in no element (a point of the reference \
                             configuration, m)"
                        ),
                    )
                }),
                (Some(e), None) if e < self.elements.len() => Ok(e),
                (e, None) => Err(Error::scene(
                    format!("output.probes[{k}].element"),
                    format!(
                        "must lie in 0..{} (global element index), got {}",
                        self.elements.len(),
                        e.map_or("nothing".into(), |e| e.to_string())
                    ),
                )),
            })
            .collect()
    }

    /// Number of DOFs, free and fixed.
    pub fn n_dofs(&self) -> usize {
        self.elements.len() * self.formulation.ndof()
    }

    /// Number of free DOFs.
    pub fn n_free_dofs(&self) -> usize {
        self.n_dofs() - self.fixed.len()
    }
}

/// The global index of DOF `name` within an element, checked against the formulation.
///
/// # Errors
/// `name` is none of the formulation's DOFs ([`Formulation::dof_names`]); the error names `field`.
pub fn dof_index(name: &str, formulation: Formulation, field: &str) -> Result<usize> {
    formulation
        .dof_names()
        .iter()
        .position(|n| *n == name)
        .ok_or_else(|| {
            Error::scene(
                field,
                format!(
                    "unknown DOF `{name}`; the {} formulation has {}",
                    formulation.name(),
                    formulation.dof_names().join(", ")
                ),
            )
        })
}

/// The boundary edges of a side or group; an error naming `field` when there are none.
fn side_edges<'m>(
    mesh: &'m Mesh,
    set: &EdgeSet,
    field: &str,
) -> Result<Vec<&'m crate::mesh::BoundaryEdge>> {
    mesh.edges_in(set).map_err(|m| Error::scene(field, m))
}

/// The boundary edges a support holds, each with the part of it held (its ends): those of its
/// side or group (an error naming `field` when there are none); with a `span`, only the side's
/// edges in it along the side (an error naming `span_field` when none is): with `clip` (a strip
/// of ground springs) every edge that overlaps the span, cut to it; without (a clamp, which
/// holds whole elements) the edges whose midpoints lie in it, whole.
fn supported_edges<'m>(
    mesh: &'m Mesh,
    set: &EdgeSet,
    span: &Option<[f64; 2]>,
    clip: bool,
    field: &str,
    span_field: &str,
) -> Result<Vec<(&'m crate::mesh::BoundaryEdge, [Vec2; 2])>> {
    let ends = |e: &crate::mesh::BoundaryEdge| [e.v1, e.v2].map(|v| mesh.vertices[v as usize]);
    let edges = side_edges(mesh, set, field)?;
    let (Some([from, to]), EdgeSet::Side(side)) = (span, set) else {
        return Ok(edges.into_iter().map(|e| (e, ends(e))).collect());
    };
    let along = |p: Vec2| match side {
        Side::Bottom | Side::Top => p.x,
        Side::Left | Side::Right => p.y,
    };
    let held: Vec<_> = edges
        .into_iter()
        .filter_map(|e| {
            let [p1, p2] = ends(e);
            let (s1, s2) = (along(p1), along(p2));
            if !clip {
                return (*from..=*to)
                    .contains(&(0.5 * (s1 + s2)))
                    .then_some((e, [p1, p2]));
            }
            // The edge's parameters where it enters and leaves the span.
            let at = |s: f64| ((s - s1) / (s2 - s1)).clamp(0.0, 1.0);
            let (t1, t2) = (at(*from), at(*to));
            let (t1, t2) = (t1.min(t2), t1.max(t2));
            (t2 - t1 > 1e-9).then(|| (e, [p1 + t1 * (p2 - p1), p1 + t2 * (p2 - p1)]))
        })
        .collect();
    if held.is_empty() {
        let what = if clip {
            "overlaps"
        } else {
            "has its midpoint in"
        };
        return Err(Error::scene(
            span_field,
            format!("no edge of side `{side:?}` {what} {:?}", [from, to]),
        ));
    }
    Ok(held)
}

/// The law of a material's interfaces in a scene: `None` for the elastic one (the model's
/// default law then applies), else its [`Strength`](law::Strength) or its [`Facet`](facet::Facet).
fn interface_law(
    spec: &crate::input::scene::InterfaceLawSpec,
) -> Option<std::sync::Arc<dyn InterfaceLaw>> {
    use crate::input::scene::InterfaceLawSpec;
    use std::sync::Arc;
    match spec {
        InterfaceLawSpec::Facet(f) => Some(Arc::new(crate::model::facet::Facet {
            f_t: f.tensile_strength,
            s: f.shear_strength,
            g_t: f.fracture_energy,
            g_s: f.fracture_energy_shear,
            f_c: f.compressive_strength,
            cap_hardening: f.cap_hardening,
            mu_0: f.friction,
            mu_inf: f.friction_residual.unwrap_or(f.friction),
            sigma_n0: f.friction_pressure.unwrap_or(f.compressive_strength),
        })),
        _ => law::Strength::from_spec(spec).map(|s| Arc::new(s) as Arc<dyn InterfaceLaw>),
    }
}
