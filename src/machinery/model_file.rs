//! Trained metamodel files: re-exported from `rths-files` (one schema for host and firmware build).
pub use rths_files::model_file::*;
