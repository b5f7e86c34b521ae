#![warn(missing_docs)]
#![forbid(unsafe_code)]
//! # rbsm: the Rigid-Bodies-Spring Model in 2D with explicit dynamics
//!
//! A structure is cut into rigid polygonal **elements**. Neighbouring elements are joined on
//! their shared edge, the **interface**, by normal and shear **penalty** springs. The motion is
//! stepped by explicit central difference. The internal forces are computed two ways that must
//! agree:
//! - **assembled**, as $K U$ with the global stiffness of the hybrid-type virtual work;
//! - **element-wise**, as the resultant of the **tractions** on each element's own boundary,
//!   with no global matrix.
//!
//! The method is that of Yagi, Takeuchi, Yamamura and Kusabuka, *An explicit dynamic method for
//! a discrete element model using the principle of hybrid-type virtual work*. The equation
//! numbers below are the paper's. `paper_notes.md` maps each equation to its code and states
//! how we read the paper where it is terse.
//!
//! ## The equations
//!
//! **Kinematics** (eqs. 5, 10). Element $e$ carries $U_e = (u, v, \theta)$ (rigid), or
//! $(u, v, \theta, \varepsilon_x, \varepsilon_y, \gamma_{xy})$ (hybrid). With
//! $\Delta x = x - x_e$ and $\Delta y = y - y_e$ measured from its centroid, the displacement is
//! $u(x) = N_e(x) U_e$ with
//! $$N_e(x) = \begin{bmatrix} 1 & 0 & -\Delta y & \Delta x & 0 & \Delta y/2 \cr 0 & 1 & \Delta x & 0 & \Delta y & \Delta x/2 \end{bmatrix}$$
//! (the first three columns for a rigid element). See [`model::formulation`].
//!
//! **Interfaces** (eqs. 6, 11, 12). On an edge shared by $a$ and $b$, with unit normal $n$ from
//! $a$ to $b$ and tangent $s$, the relative displacement is
//! $\delta(x) = N_b(x) U_b - N_a(x) U_a$. The traction is
//! $\lambda = k_n \delta_n n + k_s \delta_s s$ with
//! $$k_n = \frac{E}{(1-\nu^2)(h_a+h_b)}, \qquad k_s = \frac{E}{(1+\nu)(h_a+h_b)},$$
//! where $h_a$, $h_b$ are the distances from the centroids to the edge (plane stress). Hybrid
//! springs are $p$ times these. See [`model::Interface`] and [`model::spring_moduli`]; the
//! traction is the model's [`model::law::InterfaceLaw`], this linear one ([`model::law::Elastic`])
//! by default.
//!
//! **Assembled form** (eqs. 7–13). The principle of hybrid-type virtual work gives
//! $$M \ddot U + K U = P, \qquad K = \sum_{\rm interfaces} t \int_0^L B^T {\rm diag}(k_n, k_s) B \, d\ell + \sum_e K_e^{\rm interior},$$
//! with $B = [n\ s]^T [-N_a, N_b]$. The two-point Gauss rule is exact. $M$ is diagonal for rigid
//! elements, $\rho t\,{\rm diag}(A, A, I_p)$ (eq. 9), and block-diagonal for hybrid ones
//! (eq. 8). See [`force::evaluator::Assembled`] and [`model::mass::Mass`].
//!
//! **Element-wise form** (eqs. 15, 16). Each element's acceleration comes from the resultant
//! of the tractions $\tau_e = S \delta_e$ on its own boundary, with $\delta_e$ the neighbour's
//! displacement minus its own:
//! $$M_e \ddot U_e = t \oint_{\partial \Omega_e} N_e^T \tau_e \, d\ell + P_e.$$
//! See [`force::evaluator::ElementWise`]; `examples/element_force.rs` traces it for one element.
//!
//! **Central difference** (velocity form; `paper_notes.md` item 9), with $f = f_{\rm int}(U^n) -
//! P^n - f_c^n$:
//! $$v^{n+1/2} = v^{n-1/2} - \Delta t M^{-1} f, \qquad U^{n+1} = U^n + \Delta t v^{n+1/2}.$$
//! It is stable for $\Delta t \le \Delta t_{\rm crit} = 2/\omega_{\max}$, where $\omega_{\max}^2$
//! is the largest eigenvalue of $K \phi = \omega^2 M \phi$. See [`step::integrator`],
//! [`analysis::eigen`] and
//! [`analysis::stability`].
//!
//! **Contact** (eqs. 17–20). Edge-to-edge contact (the paper's) holds the part of a boundary
//! edge that lies inside another body by a temporary interface, with the depth measured to the
//! nearest surface face, so that its normal tractions derive from one energy; DEM point contact
//! finds a vertex that crosses an edge of another body by its crossing point and holds it by
//! one spring. Both search neighbour lists kept within a skin. See [`force::contact`].
//!
//! ## Architecture
//!
//! Data flows from the scene to the outputs through seven stages, one folder each; a stage
//! uses only the stages above it (`tests/architecture.rs` checks it), and `ARCHITECTURE.md`
//! says where to add a mesh kind, an interface law or an analysis.
//!
//! | stage | folder | owns |
//! | --- | --- | --- |
//! | 1 | [`input`] | the scene file: its types, parsing, ranges and JSON Schema |
//! | 2 | [`mesh`] | polygons and pure geometry: grids, Voronoi cells, explicit polygons, gmsh files |
//! | 3 | [`model`] | elements, interfaces, supports and loads; the formulation ($N_e$), the interface law (eq. 11), the mass, memory and input warnings |
//! | 4 | [`force`] | internal forces (the two evaluators) and contact forces |
//! | 5 | [`step`] | the explicit central-difference step, its energies and its guard |
//! | 6 | [`output`] | the files a run writes: summary, history, final state, VTK, SVG |
//! | 7 | [`analysis`] | the setup of a scene and the analyses on it: run, check, static, eigen, stability, tradeoff |
//!
//! [`error`] and [`parallel`] (chunked parallel loops) serve every stage. The `rbsm` binary
//! (`src/main.rs`) is a thin command line over [`analysis`]. Units are SI throughout: m, kg, s,
//! N, Pa, J, rad.
//!
//! ## A first use
//!
//! ```no_run
//! use rbsm::analysis::{run, setup::Setup};
//! use rbsm::input::scene::Scene;
//! let scene = Scene::from_file("examples/scenes/cantilever.json")?;
//! let setup = Setup::new(&scene, &Default::default())?;
//! let summary = run::run(&setup, &Default::default(), "out/cantilever".as_ref(), &mut
//! run::Silent)?;
//! println!("{} steps, energy drift {:e}", summary.steps, summary.energy.max_relative_drift);
//! # Ok::<(), rbsm::error::Error>(())
//! ```

pub mod analysis;
pub mod error;
pub mod force;
pub mod input;
pub mod lanes;
pub mod mesh;
pub mod model;
pub mod output;
pub mod parallel;
pub mod step;
