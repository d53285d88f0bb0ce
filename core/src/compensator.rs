//! Compensators (placeholder).
