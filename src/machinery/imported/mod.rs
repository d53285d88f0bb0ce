//! Structures imported from a finite-element program (a lab's OpenSees model): any size, sparse.
//!
//! - [`file`]: the structure file of an imported model (`rths-structure` version 2: the whole
//!   model's sparse mass, damping and stiffness, its DOFs, the specimen and the outputs), its
//!   validation, and [`ImportedStructure`], the validated model in rths units with its massless
//!   DOFs condensed out ([`ImportedStructure::condensed_dense`]).
//! - [`condense`]: static condensation of the massless DOFs (sparse Cholesky of their stiffness).
//! - [`export`]: `rths import opensees`: runs the shipped exporter (`scripts/opensees/`) with
//!   python3 and openseespy, reads its Matrix Market files into an [`ImportedFile`].
//! - [`fe`]: the host FE of an imported structure: Newmark's average acceleration on the whole
//!   sparse model, factorized once.
//! - [`split`]: the host FE in the hybrid loop (`fe-online-ats`): the operator-splitting method
//!   on the same Newmark step, a host part of core's controller.
//! - [`reduced`]: the reduced-order modal model (`rths train meta`) and its file.
//!
//! The partition is the one of every structure file: the model is the whole test structure,
//! specimen included; the numerical substructure is the model minus the specimen's stiffness at
//! its DOF (docs/opensees.md).

pub mod condense;
pub mod export;
pub mod fe;
pub mod file;
pub mod modal_reference;
pub mod reduced;
pub mod split;

pub use file::{DofLabel, ImportedFile, ImportedStructure, ImportedStructureError};
