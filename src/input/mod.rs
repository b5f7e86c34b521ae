//! Stage 1, the input: the scene file, parsed and checked against its allowed ranges. A leaf:
//! it knows nothing of the stages after it, which turn its specs into their own settings.

pub(crate) mod kinds;
pub mod names;
pub mod range;
pub mod scene;
