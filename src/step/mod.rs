//! Stage 5, the explicit step: central difference with its energy bookkeeping and divergence
//! guard ([`integrator`]).

pub mod integrator;
