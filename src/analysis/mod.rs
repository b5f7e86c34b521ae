//! Stage 7, the analyses: each takes a scene's setup and its parameters and returns a typed
//! report: a dynamic [`run`], [`statics`], [`eigen`] modes, [`stability`] limits and the
//! speed–accuracy [`tradeoff`].

pub mod eigen;
pub mod extremes;
pub mod free;
pub mod hopping;
pub mod report;
pub mod rigid_modes;
pub mod run;
pub mod stability;
pub mod statics;
pub mod tradeoff;
