//! Ground-motion records: re-exported from `rths-files` (one reader for host and firmware build).
pub use rths_files::motion::*;
