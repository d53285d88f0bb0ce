//! `rths-files`: the files an RTHS run reads, with one reader each, shared by the host CLI and the
//! firmware build script (which compiles a model and a record into the image).
//!
//! - [`motion`]: ground-motion records (PEER AT2 and two-column CSV), the four shipped records.
//! - [`model_file`]: the trained-model file schema, its reader and validator. The feature names it
//!   checks are `rths_core`'s, the order the `no_std` inference takes its coefficients in.
//! - [`history`]: time histories of a lab's FE runs (CSV, OpenSees recorder files), training data.
//! - [`nl_model_file`]: model files of the nonlinear (modal-hysteretic) metamodel, tied to their
//!   structure file by a checksum.
//! - [`hysteron_model_file`]: the floor-hysteron kind of the same format, and either kind read by
//!   its `kind`.
//! - [`reduced_model_file`]: the reduced-order model's file of an imported structure.
//! - [`rate`]: the rule that a file made at a controller rate runs only at that rate.
//! - [`readable`]: numbers in messages, never with hundreds of digits.
//! - [`structure_file`]: structure files (an N-DOF linear analytical part and its specimen).
//! - [`structure_meta`]: a structure as the controller runs it, and the structure metamodel's file.
//! - [`upload`]: a lab's model files of any kind laid out as the link carries them (the host's
//!   uploads and the firmware's compiled-in default).
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod history;
pub mod hysteron_model_file;
pub mod model_file;
pub mod motion;
pub mod nl_model_file;
pub mod rate;
pub mod readable;
pub mod reduced_model_file;
pub mod structure_file;
pub mod structure_meta;
pub mod upload;

pub use readable::readable;
