//! camera (being built)
