//! Metamodels (placeholder).
