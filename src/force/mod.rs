//! Stage 4, the forces: the internal forces of the interfaces ([`evaluator`], assembled or
//! element-wise), their plastic part where interfaces fail ([`failure`]) and the contact
//! forces between bodies ([`contact`]), and the plastic part of the hybrid elements' own
//! stress where elements yield ([`yielding`]).

pub mod contact;
pub mod evaluator;
pub mod failure;
pub mod yielding;
