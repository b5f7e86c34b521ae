//! Stage 5, the explicit step: central difference with its energy bookkeeping and divergence
//! guard ([`integrator`]), and the layout of its state in groups of four elements that a fused
//! step in lanes runs on ([`grouped`]); the local non-viscous damping of quasi-static runs
//! ([`local`]) and their stop on the unbalanced-force ratio ([`balance`]).

pub mod balance;
pub mod grouped;
pub mod integrator;
pub mod local;
