//! What the studies run on, below them: nothing here imports from [`crate::studies`] or
//! [`crate::cmd`].
//!
//! - [`drive`]: the host's one driver of core's controller (the firmware's control step and its
//!   identification tick);
//! - [`reference`]: the evaluation's reference, the plant and structure a study is built from;
//! - [`motion`], [`output`], [`plot`], [`progress`]: ground motions, files and standard output,
//!   figures, progress bars;
//! - [`model_file`], [`models`]: model files and the controller's parameters from them;
//! - [`train`]: the metamodels' training;
//! - [`identify`]: `rths identify`, a rig's characterization;
//! - [`imported`]: structures imported from OpenSees;
//! - [`structure`]: a structure file's runs: the yielding structure's reference, its learned model,
//!   the rig compensation of its hybrid runs;
//! - [`site`]: `rths site`, the experimental site.

pub mod drive;
pub mod identify;
pub mod imported;
pub mod model_file;
pub mod models;
pub mod motion;
pub mod output;
pub mod plot;
pub mod progress;
pub mod reference;
pub mod site;
pub mod structure;
pub mod train;
