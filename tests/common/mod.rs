//! Shared set-ups of the integration tests.
pub mod exact_studio;
