//! Stage 7, the analyses: each takes a scene's setup and its parameters and returns a typed
//! report: a dynamic [`run`], [`statics`], [`eigen`] modes, [`stability`] limits and the
//! speed–accuracy [`tradeoff`].

pub mod calibrate;
pub mod check;
pub mod collapse;
pub mod effective;
pub mod eigen;
pub mod free;
pub mod hopping;
pub mod limit;
pub mod rigid_modes;
pub mod run;
pub mod setup;
pub mod stability;
pub mod statics;
pub mod tradeoff;

/// What every analysis returns: a typed report that serialises to the JSON of `--json` and
/// reads as the text the command line prints.
pub trait Report: serde::Serialize {
    /// The report as lines of text.
    fn text(&self) -> String;
}
